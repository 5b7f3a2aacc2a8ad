"""An acceleration channel whose velocity step says the beam turned against the jack's clear
moment saw a bending mode, not the rigid beam: the jack's moment stands for it."""

from __future__ import annotations

import pytest

from tail_beam_id.signals.features import (
    IMU_MOMENT_READ,
    BeamModel,
    ImuImpulse,
    PressureFit,
    impact_features,
)
from tail_beam_id.signals.imu_detection import Pulse

PULSE = Pulse(1.0, 1.0, 1, 1e-4, 30.0, 0.25, 1.0 / 25600.0, 100, 110)


def features(
    model: BeamModel,
    velocity_mps: float,
    moment_nms: float,
    sigma_nms: float,
    neighbours: int = 0,
    calibrated: bool = True,
) -> dict:
    """The features of one impact with this IMU velocity step and jack moment (read with
    ``neighbours`` other impacts in the jack's fit), on a calibrated support or not."""
    return impact_features(
        model,
        PULSE,
        ImuImpulse(velocity_mps, 1e-4, 1e-4),
        PressureFit(moment_nms, sigma_nms, 1e4, 3e4, False, neighbours),
        None,
        calibrated=calibrated,
    )


@pytest.fixture(scope="module")
def model(params) -> BeamModel:
    return BeamModel.from_params(params)


def test_a_step_against_a_clear_jack_moment_is_replaced_by_it(model):
    """A negative step beside a jack moment 5 standard errors clear: the channel's moment is
    the jack's, its own reading is kept beside it, and the combined estimate is the jack's
    alone (the step's tight error would otherwise pull it below zero)."""
    got = features(model, -0.01, 5.0, 1.0)
    assert got["moment_impulse_imu_nms"] == 5.0
    assert got[IMU_MOMENT_READ] == pytest.approx(-0.01 * model.imu_moment_per_velocity)
    assert got["moment_impulse_nms"] == 5.0
    assert got["moment_impulse_sigma_nms"] == pytest.approx(1.0)
    assert got["imu_impulse_mps"] == -0.01  # the raw step is what calibration reads


def test_a_step_kept_where_the_jack_says_nothing_clear_or_agrees(model):
    """The channel's own moment stays where the jack's is within noise of zero (no evidence
    against the step), where the jack read other impacts with it (a dense flow: both reads hold
    the others'), on a support no profile calibrated, and where the step is positive (the beam
    turned the way the jack says); the combined estimate then weighs both."""
    unclear = features(model, -0.01, 2.0, 1.0)
    assert unclear["moment_impulse_imu_nms"] < 0.0 and IMU_MOMENT_READ not in unclear
    crowded = features(model, -0.01, 5.0, 1.0, neighbours=1)
    assert crowded["moment_impulse_imu_nms"] < 0.0 and IMU_MOMENT_READ not in crowded
    uncalibrated = features(model, -0.01, 5.0, 1.0, calibrated=False)
    assert IMU_MOMENT_READ not in uncalibrated
    agreeing = features(model, 0.004, 5.0, 1.0)
    assert IMU_MOMENT_READ not in agreeing
    assert agreeing["moment_impulse_imu_nms"] == pytest.approx(
        0.004 * model.imu_moment_per_velocity
    )
    assert agreeing["moment_impulse_nms"] != 5.0
