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
