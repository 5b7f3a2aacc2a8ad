"""Training replays each impact's streams in one delivery: the records it fits on are those of
the identifier fed in id_node's chunks, label for label and feature for feature."""

from __future__ import annotations

import pytest

from tail_beam_id.study.dataset import evaluation_params, settings
from tail_beam_id.study.runs import REPLAY_CHUNK_S, WHOLE_STREAM_CHUNK_S, run_set


@pytest.mark.parametrize(
    ("scene_set", "count", "true_profile"),
    [("stream", 2, False), ("varied", 6, False), ("varied", 4, True)],
)
def test_one_delivery_gives_the_chunked_records(params, scene_set, count, true_profile):
    """Records of the same impacts (every setting; drawn supports with and without their
    accelerometer) replayed in one delivery and in 10 ms chunks: the same labels (stamp,
    material, confidence, method), the same features exactly, the same extra labels."""
    seed = int(evaluation_params(params)["training_seed"]) + 2
    chosen = settings(params, every_rate=True)

    def records(chunk_s: float) -> list:
        return list(
            run_set(
                params,
                scene_set,
                count,
                seed,
                chosen,
                ["threshold"],
                true_profile=true_profile,
                without_vibration_too=scene_set == "varied",
                chunk_s=chunk_s,
            )
        )

    chunked, whole = records(REPLAY_CHUNK_S), records(WHOLE_STREAM_CHUNK_S)
    assert len(chunked) == len(whole) >= count
    labelled = 0
    for a, b in zip(chunked, whole):
        assert (a.setting, a.index, a.extra_labels) == (b.setting, b.index, b.extra_labels)
        assert (a.label is None) == (b.label is None)
        if a.label is not None:
            labelled += 1
            assert a.label.decision() == b.label.decision()
            assert dict(a.label.features) == dict(b.label.features)
            assert a.label.signals == b.label.signals
    assert labelled >= count


def test_each_recording_is_identified_with_its_own_camera(params):
    """An impact on the nominal support is identified knowing its recording's camera, as its
    user would configure it: each rate setting's label says that setting's frame (1 / camera
    rate; the exact camera's 1 us), not config/'s 5 kHz, which the models that read the frame
    would otherwise learn for every camera."""
    ev = evaluation_params(params)
    chosen = settings(params, [1.0], every_rate=True)
    frames = {s.rate_name: 1.0 / s.rates_hz["camera_frame_rate_hz"] for s in chosen}
    assert len(set(frames.values())) >= 3  # the settings differ in their camera
    seen = set()
    for record in run_set(
        params, "stream", 2, int(ev["training_seed"]) + 3, chosen, ["threshold"]
    ):
        if record.label is not None and "camera_frame_period_s" in record.label.features:
            key = record.setting.split("/")[0]
            assert record.label.features["camera_frame_period_s"] == pytest.approx(
                frames[key], rel=1e-9
            ), record.setting
            seen.add(key)
    assert seen == set(frames)
