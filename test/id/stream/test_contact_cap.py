"""A label whose contact duration cannot be trusted is capped and says why
(tail_beam_id.signals.contact_fit.unreliable, applied by tail_beam_id.stream.decision)."""

from __future__ import annotations

import copy

import pytest
from id_helpers import impact

from tail_beam_id.signals.contact_fit import (
    LONG_CONTACT,
    POOR_FIT,
    ContactFit,
    ContactFitConfig,
    unreliable,
)
from tail_beam_id.signals.contact_force import ForceReading
from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.replay import replay
from tail_beam_id.study.supports import tabulated_modes

MODES = ((3000.0, 300.0),)  # one stiff mode: half period 167 us


def _label(params, radius_m: float, section: dict | None = None, force_readout: bool = True):
    """The one label of a coal particle of ``radius_m`` dropped 1.5 m at 1.0 m on a support
    with MODES, identified knowing the support, the accelerometer fed."""
    support = copy.deepcopy(params)
    support["modes"] = tabulated_modes(params["modes"], MODES)
    support["calibration"] = {"rigid_mode_frequency_hz": 40.0}
    result = impact(support, material="coal", radius_m=radius_m, drop_height_m=1.5, position_m=1.0)
    identification = {**params["identification"], **(section or {})}
    identification["contact_fit"] = {
        **identification["contact_fit"],
        "force_readout": force_readout,
    }
    labels = replay(
        StreamIdentifier("statistical", identification, support),
        result.pressure,
        result.imu,
        [result.rebound],
        vibration=result.vibration,
    )
    assert len(labels) == 1
    return labels[0]


def test_a_contact_longer_than_the_training_saw_is_capped_with_its_reason(params):
    """A 100 mm coal's contact (about 0.9 ms of force) lasts more than long_contact_half_periods
    (5) half periods of the 3 kHz mode (167 us each; the feature says how many, from the
    duration and the mode read): its label is capped at unreliable_confidence_cap and lists
    contact_longer_than_mode; a 50 mm coal's (about 0.43 ms, 2.6 half periods) is not."""
    config = ContactFitConfig()
    long = _label(params, 0.1)
    half_periods = long.features["contact_force_half_periods"]
    assert half_periods == pytest.approx(
        2.0 * long.features["contact_force_duration_s"] * MODES[0][0], rel=0.05
    )
    assert half_periods >= config.long_contact_half_periods
    assert LONG_CONTACT in long.outside_training
    assert long.confidence <= config.unreliable_confidence_cap
    short = _label(params, 0.05)
    assert short.features["contact_force_half_periods"] < config.long_contact_half_periods
    assert LONG_CONTACT not in short.outside_training
    assert short.confidence > config.unreliable_confidence_cap


def test_without_the_force_read_out_nothing_is_read_or_capped(params):
    """The force read-out is off by default (it costs 2-3x the fit): the 100 mm coal's label
    then has no contact_force features and no cap from them."""
    label = _label(params, 0.1, force_readout=False)
    assert not [name for name in label.features if name.startswith("contact_force")]
    assert LONG_CONTACT not in label.outside_training
    assert "contact_duration_s" in label.features  # the half-sine the models read is still there


def test_a_poor_fit_is_capped_with_its_reason(params):
    """With the poor-fit thresholds at zero every fit is poor: the 50 mm coal's label is then
    capped and lists contact_fit_poor (and only that)."""
    contact_fit = {
        **params["identification"]["contact_fit"],
        "poor_fit_unexplained": 0.0,
        "poor_fit_noise_ratio": 0.0,
    }
    label = _label(params, 0.05, {"contact_fit": contact_fit})
    assert POOR_FIT in label.outside_training
    assert LONG_CONTACT not in label.outside_training
    assert label.confidence <= contact_fit["unreliable_confidence_cap"]


def test_a_pole_without_oscillation_is_no_mode():
    """A ring-down pole read as a pure decay (0 Hz) does not make every contact long (and does
    not divide by zero); a 3 kHz mode beside it makes a 1 ms force 6 half periods long."""
    force = ForceReading(
        duration_s=1e-3,
        start_s=0.0,
        rise_s=3e-4,
        exponent=1.5,
        chi=1.0,
        residual_noise_ratio=1.0,
        half_sine_s=7e-4,
        unexplained=0.001,
    )
    config = ContactFitConfig()
    assert unreliable(ContactFit(7e-4, 0.0, (0.0,), force), config) == ()
    assert unreliable(ContactFit(7e-4, 0.0, (0.0, 3000.0), force), config) == (LONG_CONTACT,)
