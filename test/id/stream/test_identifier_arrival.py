"""The identifier when one topic's messages arrive far behind the other's (a backlogged IMU on
a busy middleware): it must neither crash nor lose the IMU data it has not examined yet."""

from __future__ import annotations

import copy

import numpy as np
from id_helpers import stream

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import replay

STAMPS = [0.3, 0.9, 1.5]


def _caving_stream(params):
    """Three 60 mm impacts with the IMU and camera at 10 kHz: at that rate a second of IMU
    backlog is far beyond what trimming keeps by the newest stamp."""
    fast = copy.deepcopy(params)
    fast["sensors"] = {**fast["sensors"], "imu_rate_hz": 10000.0, "camera_frame_rate_hz": 10000.0}
    commands = [
        (stamp, {"material": material, "radius_m": 0.06, "drop_height_m": 3.0, "position_m": 1.0})
        for stamp, material in zip(STAMPS, ("sandstone", "coal", "marble"))
    ]
    return fast, stream(fast, commands, 2.2)


def test_imu_declared_stopped_then_resuming_does_not_break_the_identifier(params):
    """All pressure first, then the whole IMU stream a second late: the IMU is declared stopped
    (it lags by more than stream_timeout_s), its old samples are trimmed, and then it resumes.
    Every impact is still labelled, from the signals the label names, without overconfidence."""
    fast, (pressure, imu, rebounds, _) = _caving_stream(params)
    identifier = StreamIdentifier(params=fast["identification"])
    identifier.add_pressure(pressure.stamp_s, pressure.pressure_pa)
    identifier.poll()
    for low in np.arange(0.0, 2.2, 0.01):
        take = (imu.stamp_s >= low) & (imu.stamp_s < low + 0.01)
        identifier.add_imu(
            imu.stamp_s[take], imu.angular_velocity_radps[take], imu.linear_acceleration_mps2[take]
        )
        identifier.poll()
    for rebound in rebounds:
        identifier.add_rebound(rebound.stamp_s, rebound.velocity_mps)
    labels = identifier.poll() + identifier.flush()
    assert len(labels) == len(STAMPS)
    for label, stamp in zip(sorted(labels, key=lambda label: label.impact_stamp_s), STAMPS):
        assert abs(label.impact_stamp_s - stamp) < 1e-3
        assert "imu" not in label.signals and label.confidence < 0.9


def test_in_order_delivery_gives_the_same_labels_for_any_chunking(params):
    """In-order delivery in 3, 10 or 25 ms chunks gives the same three labels and confidences."""
    fast, (pressure, imu, rebounds, _) = _caving_stream(params)
    runs = [
        [
            (label.impact_stamp_s, label.material, label.confidence)
            for label in replay(
                StreamIdentifier(params=fast["identification"]), pressure, imu, rebounds, chunk_s=c
            )
        ]
        for c in (0.003, 0.01, 0.025)
    ]
    assert len(runs[0]) == 3
    assert runs[0] == runs[1] == runs[2]
