"""Labelled impacts from the project's own simulator: the scene sets of the evaluation
(paper, stream, mismatch) and the training set, each drawn from its own seed.

Each impact is simulated at every sensor setting asked for (noise factor x sample rates),
each with its own pre-contact baseline, as one short stream. A setting or drawn support with
the tail-beam accelerometer keeps the simulated ``vibration`` blocks in its result (and the
runs feed them to the identifier, as id_node does); one without it has no blocks
(``VibrationBlocks.empty()``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from tail_beam_id.study.supports import SupportDraw, draw_support, support_ranges
from tail_beam_sim.config import section
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.fidelity import FidelitySettings
from tail_beam_sim.physics.scene import Scene, SensorSpec
from tail_beam_sim.physics.simulate import SimulationResult, simulate, simulate_many
from tail_beam_sim.physics.stream import CHANNELS, WITHOUT_ACCELEROMETER, StreamSimulator

# Evaluation scene sets. ``foreign`` records drawn supports as continuous streams of stream-scene
# impacts, ``foreign_paper`` the same supports with the paper scene's (support_streams;
# tail_beam_id.study.runs.run_foreign evaluates them), the others are single impacts.
SCENE_SETS = (
    "paper",
    "stream",
    "mismatch",
    "foreign",
    "foreign_paper",
    "structures",
    "structures_paper",
)
# Foreign sets -> the scene whose impacts strike their supports, and the ranges they are drawn
# from (identification.evaluation.supports): ``structures`` draws each support's bending modes
# from a beam of its own (tail_beam_id.study.supports.draw_structure).
FOREIGN_SCENES = {
    "foreign": "stream",
    "foreign_paper": "paper",
    "structures": "stream",
    "structures_paper": "paper",
}
FOREIGN_RANGES = {
    "foreign": "foreign",
    "foreign_paper": "foreign",
    "structures": "structures",
    "structures_paper": "structures",
}
# Training scene sets whose every impact strikes its own drawn support, with its own sensor
# rates and noise (tail_beam_id.study.supports), from these ranges; DRAWN_SCENES: the scene whose
# impacts strike them (varied_paper: the paper scene's, which the stream's ranges hold only as
# one point among many, on supports other than config/'s).
DRAWN_SETS = {"varied": "training", "varied_paper": "training"}
DRAWN_SCENES = {"varied": "stream", "varied_paper": "paper"}
DRAWN_SETTING = "drawn"
PERTURBED_SUPPORT = ("beam_inertia_about_hinge_kgm2", "jack_damping_nspm", "oil_bulk_modulus_pa")


RATE_FIELDS = (
    "pressure_rate_hz",
    "imu_rate_hz",
    "camera_frame_rate_hz",
)  # every setting names these, Hz
VIBRATION_FIELD = (
    "vibration_rate_hz"  # the accelerometer's rate, Hz; 0 or absent = no accelerometer
)
VIBRATION_RATE_RANGE_HZ = (1000.0, 100000.0)  # what sensors.vibration_rate_hz accepts, Hz


@dataclass(frozen=True)
class Setting:
    """One sensor setting: noise factor (x nominal RMS), the named sample rates of pressure,
    IMU and camera (Hz) and the tail-beam accelerometer's rate (Hz; 0 = none at this site)."""

    noise_factor: float
    rate_name: str
    rates_hz: Mapping[str, float]
    vibration_rate_hz: float = 0.0

    @property
    def key(self) -> str:
        return f"{self.rate_name}/x{self.noise_factor:g}"

    @property
    def has_vibration(self) -> bool:
        return self.vibration_rate_hz > 0.0

    def sensors(self) -> dict[str, float]:
        """The ``sensors`` parameters this setting sets (the accelerometer's rate only when it
        has one)."""
        return {
            **self.rates_hz,
            **({VIBRATION_FIELD: self.vibration_rate_hz} if self.has_vibration else {}),
        }


@dataclass
class LabelledImpact:
    """One simulated impact: its command, support and contact law, and each setting's result."""

    index: int
    command: dict[str, Any]
    support_scale: dict[str, float]
    contact_model: str
    results: dict[str, SimulationResult]
    support: SupportDraw | None = None

    @property
    def is_coal(self) -> bool:
        return next(iter(self.results.values())).scene.impact.material.is_coal


def evaluation_params(params: Mapping[str, Any]) -> Mapping[str, Any]:
    """The ``identification.evaluation`` parameter section."""
    return section(section(params, "identification"), "evaluation")


def settings(
    params: Mapping[str, Any],
    noise_factors: Sequence[float] | None = None,
    rate_names: Sequence[str] | None = None,
    every_rate: bool = False,
) -> list[Setting]:
    """Every (noise factor, rates) combination asked for (default: the config's noise factors
    and default rates, or every rate with ``every_rate``)."""
    ev = evaluation_params(params)
    rates = ev["rates"]
    names = (
        list(rate_names)
        if rate_names
        else (list(rates) if every_rate else list(ev["default_rates"]))
    )
    for name in names:
        if name not in rates:
            raise InputError("rates", name, f"must be one of {', '.join(rates)}")
    factors = list(noise_factors) if noise_factors else [float(f) for f in ev["noise_factors"]]
    for factor in factors:
        if not (factor >= 0.0 and math.isfinite(factor)):
            raise InputError("noise", factor, "must be a finite factor >= 0")
    return [
        Setting(
            float(f),
            name,
            {k: float(rates[name][k]) for k in RATE_FIELDS},
            _vibration_rate(rates[name], name),
        )
        for name in names
        for f in factors
    ]


def _vibration_rate(rates: Mapping[str, Any], name: str) -> float:
    """A setting's accelerometer rate (Hz), checked: 0 (or absent) for none, else in range."""
    for field in RATE_FIELDS:
        if field not in rates:
            raise InputError(
                f"identification.evaluation.rates.{name}.{field}", None, "missing (Hz)"
            )
    value = rates.get(VIBRATION_FIELD, 0.0)
    low, high = VIBRATION_RATE_RANGE_HZ
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not (value == 0.0 or low <= value <= high)
    ):
        raise InputError(
            f"identification.evaluation.rates.{name}.{VIBRATION_FIELD}",
            value,
            f"must be 0 (no accelerometer) or in [{low:g}, {high:g}] Hz",
        )
    return float(value)


def draw_commands(
    params: Mapping[str, Any], scene_set: str, count: int, seed: int
) -> Iterator[tuple[dict[str, Any], dict[str, float], str]]:
    """(impact command, support scale factors, contact law) for ``count`` impacts of a set."""
    if scene_set not in SCENE_SETS and scene_set not in DRAWN_SETS:
        raise InputError("scene_set", scene_set, f"must be one of {', '.join(SCENE_SETS)}")
    ev = evaluation_params(params)
    ranges = ev["paper" if scene_set == "paper" else "stream"]
    mix = ev["material_mix"]
    names = sorted(mix)
    weights = np.array([float(mix[n]) for n in names])
    materials = params["materials"]
    rng = np.random.default_rng(seed)
    for _ in range(count):
        material = names[int(rng.choice(len(names), p=weights / weights.sum()))]
        low_r, high_r = ranges["radius_m"]
        radius = float(math.exp(rng.uniform(math.log(low_r), math.log(high_r))))
        height = float(rng.uniform(*ranges["drop_height_m"]))
        position = float(rng.uniform(*ranges["position_m"]))
        command: dict[str, Any] = {
            "material": material,
            "radius_m": radius,
            "drop_height_m": height,
            "position_m": position,
        }
        if ranges["restitution"] == "range":
            command["restitution"] = float(rng.uniform(*materials[material]["restitution_range"]))
        scale = {name: 1.0 for name in PERTURBED_SUPPORT}
        law = "calibrated"
        if scene_set == "mismatch":
            span = float(ev["support_perturbation"])
            scale = {
                name: float(rng.uniform(1.0 - span, 1.0 + span)) for name in PERTURBED_SUPPORT
            }
            laws = ev["mismatch_contact_models"]
            law = laws[int(rng.integers(len(laws)))]
        yield command, scale, law


CHUNK_IMPACTS = 64  # impacts of a set simulated together (simulate_many)


def simulate_set(
    params: Mapping[str, Any],
    scene_set: str,
    count: int,
    seed: int,
    chosen: Sequence[Setting],
    tier: str | None = None,
) -> Iterator[LabelledImpact]:
    """Simulate ``count`` impacts of ``scene_set`` at every setting in ``chosen`` (a drawn set:
    once, on its own support at its own rates and noise; ``chosen`` does not apply)."""
    ev = evaluation_params(params)
    tier = tier or ev["tier"]
    if scene_set in DRAWN_SETS:
        yield from _simulate_drawn(params, scene_set, count, seed, tier)
        return
    noise_seeds = np.random.SeedSequence(seed).spawn(count)
    fidelity = FidelitySettings.from_params(
        params
    )  # the given parameters' bending modes (config/'s by default)
    # Impacts are simulated CHUNK_IMPACTS at a time: simulate_many solves and senses many
    # impacts together (the same results as one by one, to rounding), and each impact's
    # settings differ in their sensors only, so each impact is solved once and each setting's
    # sensors sample that motion.
    pending: list[tuple[int, dict[str, Any], dict[str, float], str]] = []
    scenes: list[Scene] = []
    for index, (command, scale, law) in enumerate(draw_commands(params, scene_set, count, seed)):
        varied = {**params, "support": dict(params["support"])}
        for name, factor in scale.items():
            varied["support"][name] = float(params["support"][name]) * factor
        noise_seed = int(noise_seeds[index].generate_state(1)[0])
        # the impact and its support validated once; each setting changes the sensors only
        base: Scene | None = None
        for setting in chosen:
            varied["sensors"] = {**params["sensors"], **setting.sensors(), "seed": noise_seed}
            if base is None:
                base = scene = Scene.from_params(
                    varied,
                    {
                        **command,
                        "contact_model": law,
                        "pre_contact_s": ev["pre_contact_s"],
                        "window_s": ev["window_s"],
                    },
                )
            else:
                scene = replace(base, sensors=SensorSpec.from_params(varied["sensors"]))
            scenes.append(replace(scene, sensors=scene.sensors.scaled_noise(setting.noise_factor)))
        pending.append((index, command, scale, law))
        if len(pending) == CHUNK_IMPACTS:
            yield from _simulated(pending, scenes, chosen, tier, fidelity)
            pending, scenes = [], []
    if pending:
        yield from _simulated(pending, scenes, chosen, tier, fidelity)


def _simulated(
    pending: Sequence[tuple[int, dict[str, Any], dict[str, float], str]],
    scenes: Sequence[Scene],
    chosen: Sequence[Setting],
    tier: str,
    fidelity: FidelitySettings,
) -> Iterator[LabelledImpact]:
    """The impacts ``pending``, each at every setting of ``chosen`` (``scenes``, impact after
    impact), simulated together."""
    flags = [setting.has_vibration for setting in chosen]
    outcomes = simulate_many(scenes, tier=tier, settings=fidelity, vibration=flags * len(pending))
    for k, (index, command, scale, law) in enumerate(pending):
        mine = outcomes[k * len(chosen) : (k + 1) * len(chosen)]
        results = {setting.key: result for setting, result in zip(chosen, mine)}
        yield LabelledImpact(index, command, scale, law, results)


def _simulate_drawn(
    params: Mapping[str, Any], scene_set: str, count: int, seed: int, tier: str
) -> Iterator[LabelledImpact]:
    """Impacts of the set's scene (DRAWN_SCENES), each on its own support drawn from the set's
    ranges."""
    ev = evaluation_params(params)
    ranges = support_ranges(ev, DRAWN_SETS[scene_set])
    support_rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
    vibration_rng = np.random.default_rng(np.random.SeedSequence([seed, 3]))
    noise_seeds = np.random.SeedSequence(seed).spawn(count)
    for index, (command, _, _) in enumerate(
        draw_commands(params, DRAWN_SCENES[scene_set], count, seed)
    ):
        draw = draw_support(ranges, support_rng, vibration_rng, params["modes"])
        varied = draw.apply(params)
        varied["sensors"]["seed"] = int(noise_seeds[index].generate_state(1)[0])
        scene = Scene.from_params(
            varied,
            {
                **command,
                "contact_model": draw.contact_model,
                "pre_contact_s": ev["pre_contact_s"],
                "window_s": ev["window_s"],
            },
        )
        result = simulate(
            scene,
            tier=tier,
            settings=FidelitySettings.from_params(varied),
            vibration=draw.vibration_rate_hz > 0.0,
        )
        yield LabelledImpact(index, command, {}, draw.contact_model, {DRAWN_SETTING: result}, draw)


@dataclass
class SupportStream:
    """A continuous recording of one drawn support: its streams and every impact's truth."""

    support: SupportDraw
    params: dict[
        str, Any
    ]  # the merged parameters describing the support (what a perfect profile would hold)
    pressure: Any
    imu: Any
    rebounds: list[Any]
    truths: list[dict[str, Any]]
    vibration: Any = (
        None  # the accelerometer's blocks (VibrationBlocks); None when the support has none
    )
    # where the camera saw each particle strike (ImpactPoint), when it reports it
    points: list[Any] = dataclasses.field(default_factory=list)


def support_streams(
    params: Mapping[str, Any],
    supports: int,
    impacts_per_support: int,
    seed: int,
    which: str = "foreign",
    tier: str | None = None,
    setting: Setting | None = None,
    scene: str = "stream",
) -> Iterator[SupportStream]:
    """``supports`` drawn supports, each recorded as one continuous stream of
    ``impacts_per_support`` impacts of ``scene`` (stream or paper; the beam still swaying from
    the earlier ones, as on a face), like the bags a user records: what self-calibration works
    from. With ``setting`` every support carries that setting's sensors (rates, accelerometer,
    noise factor) instead of drawn ones; the supports are the same for any setting and scene,
    the impacts for any setting."""
    ev = evaluation_params(params)
    ranges = support_ranges(ev, which)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 2]))
    vibration_rng = np.random.default_rng(np.random.SeedSequence([seed, 4]))
    for index in range(supports):
        draw = draw_support(ranges, rng, vibration_rng, params["modes"])
        if setting is not None:
            draw = draw.with_sensors(
                setting.rates_hz, setting.vibration_rate_hz, setting.noise_factor
            )
        commands = [
            c for c, _, _ in draw_commands(params, scene, impacts_per_support, seed + 1000 * index)
        ]
        yield record_support(params, draw, draw.apply(params), commands, rng, tier)


def study_simulator(
    varied: dict[str, Any], tier: str, impacts: int, channels: Collection[str] = CHANNELS
) -> StreamSimulator:
    """A stream simulator of the support ``varied`` describes (its ``stream`` section set in
    place) for a study's recording: ``impacts`` commands queued at once with their own contact
    stamps, however close, solved at ``tier``, sampling the sensors ``channels`` alone."""
    varied["stream"] = {
        **varied.get("stream", {}),
        "tier": tier,
        "min_impact_gap_s": 0.0,
        "command_lead_s": 0.001,
        "max_queued_impacts": impacts + 1,
    }
    return StreamSimulator.from_params(varied, channels=channels)


def record_support(
    params: Mapping[str, Any],
    draw: SupportDraw,
    varied: dict[str, Any],
    commands: Sequence[Mapping[str, Any]],
    rng: np.random.Generator,
    tier: str | None = None,
) -> SupportStream:
    """One support (``varied``: its merged parameters, ``draw`` what was drawn of it) recorded
    as one continuous stream of ``commands``, each contact stream_gap_s to 1.5 stream_gap_s
    after the one before (``rng`` draws the gaps and the sensors' noise seed)."""
    ev = evaluation_params(params)
    varied["sensors"]["seed"] = int(rng.integers(2**31))
    # a support without the accelerometer: its samples are not simulated at all
    channels = CHANNELS if draw.vibration_rate_hz > 0.0 else WITHOUT_ACCELEROMETER
    simulator = study_simulator(varied, tier or ev["tier"], len(commands), channels)
    gap_s = float(ev["stream_gap_s"])
    stamp = float(ev["pre_contact_s"]) * 2.0
    for command in commands:
        simulator.submit(dict(command), contact_stamp_s=stamp)
        stamp += gap_s * (1.0 + 0.5 * rng.uniform())
    chunk = simulator.advance(stamp + 0.2)
    return SupportStream(
        draw,
        varied,
        chunk.pressure,
        chunk.imu,
        [r for _, r in chunk.rebounds],
        [t for _, t in chunk.truths],
        chunk.vibration if draw.vibration_rate_hz > 0.0 else None,
        [p for _, p in chunk.points],
    )
