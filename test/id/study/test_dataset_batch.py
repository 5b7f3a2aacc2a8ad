"""A scene set simulated many impacts at a time (simulate_many's group path) gives, impact by
impact and setting by setting, what simulate gives each scene alone: the same scenes, the same
noise, the signals to 1e-11 of each."""

from __future__ import annotations

from same_result import assert_same_result

from tail_beam_id.study.dataset import evaluation_params, settings, simulate_set
from tail_beam_sim.physics.simulate import simulate


def test_a_set_simulated_together_is_each_scene_simulated_alone(params):
    """Six impacts of the stream set at two noise levels and every rate (the mismatch set: each
    on its own perturbed support) match simulate of each scene at the set's tier."""
    ev = evaluation_params(params)
    chosen = settings(params, noise_factors=[1.0, 2.0], every_rate=True)
    seed = int(ev["training_seed"]) + 7
    for scene_set in ("stream", "mismatch"):
        impacts = list(simulate_set(params, scene_set, 6, seed, chosen))
        assert [i.index for i in impacts] == list(range(6))
        for impact in impacts:
            assert list(impact.results) == [setting.key for setting in chosen]
            for setting in chosen:
                result = impact.results[setting.key]
                alone = simulate(result.scene, tier=ev["tier"], vibration=setting.has_vibration)
                assert_same_result(result, alone)
