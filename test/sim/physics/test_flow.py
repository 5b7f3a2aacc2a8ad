"""The drawing opening's flow: share curve, lump statistics, windows, share truth, determinism
and the errors of bad parameters."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from scipy.special import ndtr, ndtri

from tail_beam_sim.config import default_config_dir, load_parameters
from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.flow import FlowRun, ShareTally, simulate_flow
from tail_beam_sim.physics.lumps import FlowParams, LumpSource, WindowStateError
from tail_beam_sim.physics.materials import material_table
from tail_beam_sim.physics.share_curve import ShareCurve
from tail_beam_sim.physics.support import Support

BASE = load_parameters(
    [default_config_dir() / "sim_node.yaml", default_config_dir() / "flow.yaml"]
)
MATERIALS = material_table(BASE)
SUPPORT = Support.from_params(BASE["support"], MATERIALS)


def params(**flow) -> dict:
    out = copy.deepcopy(BASE)
    out["flow"].update(flow)
    return out


def flow_params(**flow) -> FlowParams:
    return FlowParams.from_params(params(**flow)["flow"], MATERIALS, SUPPORT)


def lumps_of(flow: FlowParams, open_s: float, close_s: float, seed: int = 3) -> list:
    source = LumpSource(flow, MATERIALS, seed)
    source.open(open_s)
    lumps = source.take_until(close_s)
    source.close(close_s)
    return lumps + source.take_until(close_s + flow.onset_delay_s + 1.0)


# --- the share curve --------------------------------------------------------------------------


def test_share_curve_is_linear_between_points_and_held_beyond():
    """The share curve interpolates linearly and holds its end values."""
    curve = ShareCurve.of([100.0, 300.0], [0.0, 0.5])
    assert curve.at(0.0) == 0.0
    assert curve.at(200.0) == pytest.approx(0.25)
    assert curve.at(1e6) == 0.5


@pytest.mark.parametrize(
    "mass, share, field, words",
    [
        ([0.0, 100.0], [0.0, 1.2], "flow.share_gangue[1]", "[0, 1]"),
        ([0.0, 100.0], [-0.1, 0.2], "flow.share_gangue[0]", "[0, 1]"),
        ([0.0, 100.0, 200.0], [0.0, 0.2], "flow.share_gangue", "one share per drawn mass"),
        ([0.0, 100.0, 100.0], [0.0, 0.2, 0.3], "flow.share_drawn_mass_kg[2]", "increase"),
        ([-5.0, 100.0], [0.0, 0.2], "flow.share_drawn_mass_kg[0]", ">= 0"),
        ([], [], "flow.share_drawn_mass_kg", "at least one"),
        ([0.0, "a"], [0.0, 0.2], "flow.share_drawn_mass_kg[1]", "number"),
        ([0.0, 1.0], [0.0, math.nan], "flow.share_gangue[1]", "number"),
    ],
)
def test_a_share_curve_that_is_not_a_share_is_refused_by_name(mass, share, field, words):
    """A share outside [0, 1], unequal lengths, masses not increasing: refused naming the entry."""
    with pytest.raises(InputError) as error:
        ShareCurve.of(mass, share)
    assert error.value.field == field
    assert words in error.value.allowed


# --- bad parameters ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "override, field",
    [
        ({"lumps_per_s": 0.0}, "flow.lumps_per_s"),
        ({"lumps_per_s": 5000.0}, "flow.lumps_per_s"),
        ({"mass_rate_kgps": -1.0}, "flow.mass_rate_kgps"),
        ({"rate_kind": "tonnes"}, "flow.rate_kind"),
        ({"radius_log_sigma": 3.0}, "flow.radius_log_sigma"),
        ({"radius_median_m": 0.2}, "flow.radius_median_m"),
        ({"radius_m": [0.02, 0.9]}, "flow.radius_m[1]"),
        ({"radius_m": [0.05, 0.02]}, "flow.radius_m[1]"),
        ({"drop_height_m": [0.0, 2.0]}, "flow.drop_height_m[0]"),
        ({"position_m": [0.3, 9.0]}, "flow.position_m[1]"),
        ({"coal_material": "sandstone"}, "flow.coal_material"),
        ({"gangue_materials": ["coal"]}, "flow.gangue_materials[0]"),
        ({"gangue_materials": []}, "flow.gangue_materials"),
        ({"share_gangue": [0.0, 0.0, 0.2, 0.5, 1.5]}, "flow.share_gangue[4]"),
        ({"share_gangue": [0.0, 0.5]}, "flow.share_gangue"),
        ({"interval_s": 0.0}, "flow.interval_s"),
    ],
)
def test_bad_flow_parameters_are_refused_naming_the_field(override, field):
    """Rates, sizes, ranges and materials out of range are refused naming the flow field."""
    with pytest.raises(InputError) as error:
        flow_params(**override)
    assert error.value.field == field
    assert "must" in error.value.allowed


def test_shipped_flow_section_is_valid():
    """config/flow.yaml passes its own checks and its curve rises from pure coal."""
    flow = flow_params()
    assert flow.share.at(0.0) == 0.0 and flow.share.at(1e9) > 0.5


# --- the lumps --------------------------------------------------------------------------------


def test_lump_rate_is_poisson_at_lumps_per_s():
    """200 lumps/s over 50 s: the count is within 4 standard deviations of 10 000, and the
    gaps' coefficient of variation is 1 (exponential)."""
    flow = flow_params(lumps_per_s=200.0)
    lumps = lumps_of(flow, 0.0, 50.0)
    assert abs(len(lumps) - 10_000) < 4 * math.sqrt(10_000)
    gaps = np.diff([lump.contact_stamp_s for lump in lumps])
    assert np.all(gaps >= 0)
    assert np.std(gaps) / np.mean(gaps) == pytest.approx(1.0, abs=0.05)


def test_mass_rate_is_met_whatever_the_lumps_weigh():
    """rate_kind mass: over 40 s the mass that struck is mass_rate_kgps x 40 s, within four
    standard deviations of the renewal process (gaps exponential with mean m / rate: relative
    sd sqrt(E[m^2] / N) / E[m]), with pure gangue (heavier lumps, fewer) as with pure coal."""
    for share in (0.0, 1.0):
        flow = flow_params(rate_kind="mass", mass_rate_kgps=150.0, share_gangue=[share] * 5)
        lumps = lumps_of(flow, 0.0, 40.0)
        masses = np.array([lump.mass_kg for lump in lumps])
        sd = math.sqrt(np.mean(masses**2) / masses.size) / np.mean(masses)
        assert masses.sum() == pytest.approx(150.0 * 40.0, rel=4 * sd)
        assert all(lump.is_gangue == bool(share) for lump in lumps)


def test_radius_follows_the_truncated_log_normal():
    """The radii stay in radius_m and their empirical CDF is within the 99.9 % Kolmogorov band
    of the truncated log-normal at five radii."""
    flow = flow_params(lumps_per_s=500.0)
    radii = np.array([lump.radius_m for lump in lumps_of(flow, 0.0, 20.0)])
    lo, hi = flow.radius_m
    assert radii.min() >= lo and radii.max() <= hi
    med, sigma = flow.radius_median_m, flow.radius_log_sigma
    a, b = ndtr(math.log(lo / med) / sigma), ndtr(math.log(hi / med) / sigma)
    band = 1.95 / math.sqrt(radii.size)
    for r in (0.02, 0.03, 0.04, 0.06, 0.09):
        expected = (ndtr(math.log(r / med) / sigma) - a) / (b - a)
        assert np.mean(radii <= r) == pytest.approx(expected, abs=band)
    assert np.median(radii) == pytest.approx(med * math.exp(sigma * ndtri((a + b) / 2)), rel=0.03)


def test_heights_and_positions_are_uniform_in_the_opening():
    """Drop heights and strike positions stay in their ranges with the uniform mean."""
    flow = flow_params(lumps_per_s=500.0)
    lumps = lumps_of(flow, 0.0, 10.0)
    for name, (lo, hi) in (("drop_height_m", flow.drop_height_m), ("position_m", flow.position_m)):
        values = np.array([getattr(lump, name) for lump in lumps])
        assert values.min() >= lo and values.max() <= hi
        assert np.mean(values) == pytest.approx(
            (lo + hi) / 2, abs=4 * (hi - lo) / math.sqrt(12 * values.size)
        )


def test_gangue_share_by_mass_follows_the_curve():
    """A constant share of 0.3 by mass: over many lumps the gangue mass share is 0.3 and the
    count share the density-weighted p = s rho_c / (s rho_c + (1 - s) rho_g)."""
    s = 0.3
    flow = flow_params(lumps_per_s=500.0, share_gangue=[s] * 5)
    lumps = lumps_of(flow, 0.0, 20.0)
    gangue = [lump for lump in lumps if lump.is_gangue]
    mass_share = sum(lump.mass_kg for lump in gangue) / sum(lump.mass_kg for lump in lumps)
    assert mass_share == pytest.approx(s, abs=0.03)
    rho_c = MATERIALS["coal"].density_kgpm3
    rho_g = np.mean([MATERIALS[name].density_kgpm3 for name in flow.gangue_materials])
    p = s * rho_c / (s * rho_c + (1 - s) * rho_g)
    assert len(gangue) / len(lumps) == pytest.approx(
        p, abs=4 * math.sqrt(p * (1 - p) / len(lumps))
    )
    assert {lump.material for lump in gangue} == set(flow.gangue_materials)


def test_window_releases_lumps_only_while_open():
    """The first lump strikes onset_delay_s after the opening, none is released after the
    closing, and the drawn mass carries across windows."""
    flow = flow_params(lumps_per_s=100.0, onset_delay_s=0.5)
    source = LumpSource(flow, MATERIALS, 1)
    assert source.take_until(10.0) == []
    source.open(1.0)
    first = source.take_until(3.0)
    assert first[0].contact_stamp_s == pytest.approx(1.5)
    source.close(3.0)
    late = source.take_until(20.0)
    assert all(lump.contact_stamp_s <= 3.5 for lump in late)
    assert all(lump.contact_stamp_s > 3.0 for lump in late)
    drawn = source.drawn_mass_kg
    source.open(30.0)
    again = source.take_until(31.0)
    assert again[0].drawn_mass_kg == pytest.approx(drawn)


def test_window_command_for_a_window_in_that_state_is_refused_by_name():
    """Opening an open window, closing a closed one, an unknown action: refused by name."""
    run = FlowRun(params())
    with pytest.raises(WindowStateError) as error:
        run.command("close")
    assert error.value.field == "window_cmd.action" and "already closed" in error.value.allowed
    run.command("open")
    with pytest.raises(WindowStateError) as error:
        run.command("open")
    assert "already open" in error.value.allowed
    with pytest.raises(InputError) as error:
        run.command("ajar")
    assert error.value.field == "window_cmd.action"


# --- share truth and determinism --------------------------------------------------------------


def test_share_tally_reports_each_ended_interval_once():
    """Each interval is reported once after its end, with its counts; empty ones while lumps
    may reach the beam with null shares."""
    windows = [(0.2, math.inf)]
    tally = ShareTally(1.0, 0.5, windows)
    tally.add(0.7, 2.0, False)
    tally.add(1.1, 1.0, True)
    tally.add(1.9, 3.0, False)
    assert tally.report(0.9) == []
    first, second = tally.report(2.0)
    assert (first.start_stamp_s, first.end_stamp_s, first.lumps) == (0.0, 1.0, 1)
    assert first.share_by_mass == 0.0
    assert second.share_by_mass == pytest.approx(0.25) and second.share_by_count == 0.5
    assert second.drawn_mass_kg == pytest.approx(6.0)
    windows[-1] = (0.2, 2.0)
    empty = tally.report(4.0)
    assert [s.start_stamp_s for s in empty] == [2.0]  # lumps reach the beam until 2.5 s
    assert empty[0].share_by_mass is None and empty[0].lumps == 0
    assert tally.report(4.0) == []


FAST_RISE = {
    "lumps_per_s": 40.0,
    "onset_delay_s": 0.1,
    "share_drawn_mass_kg": [0.0, 30.0, 60.0],
    "share_gangue": [0.0, 0.0, 1.0],
}


@pytest.fixture(scope="module")
def record():
    return simulate_flow(params(**FAST_RISE), 4.0, seed=5)


def test_a_run_shows_pure_coal_then_the_boundary_and_the_share_rising(record):
    """A run's share intervals start at pure coal and rise once the boundary arrives."""
    shares = [s.share_by_mass for s in record.shares]
    assert [s.start_stamp_s for s in record.shares] == [0.0, 1.0, 2.0, 3.0]
    assert shares[0] == 0.0
    assert shares[-1] > 0.5
    assert all(later >= 0 for later in shares)


def test_share_truth_matches_the_lump_truths(record):
    """Each interval's counts, recomputed from the impact_truth objects (their contact stamps,
    labels and masses), are what gangue_share_truth says."""
    truths = [truth for _, truth in record.truths]
    assert {t["impact_id"] for t in truths} <= {lump.impact_id for lump in record.lumps}
    by_id = {lump.impact_id: lump for lump in record.lumps}
    for interval in record.shares:
        inside = [
            lump
            for lump in by_id.values()
            if interval.start_stamp_s <= lump.contact_stamp_s < interval.end_stamp_s
        ]
        assert interval.lumps == len(inside)
        assert interval.gangue_lumps == sum(lump.is_gangue for lump in inside)
        assert interval.mass_kg == pytest.approx(sum(lump.mass_kg for lump in inside))
    for truth in truths:
        lump = by_id[truth["impact_id"]]
        assert truth["label"] == ("gangue" if lump.is_gangue else "coal")
        assert truth["mass_kg"] == pytest.approx(lump.mass_kg)
        assert truth["contact_start_stamp"] == pytest.approx(lump.contact_stamp_s)
        assert truth["drawn_mass_kg"] == pytest.approx(lump.drawn_mass_kg)


def test_every_lump_gets_one_rebound_and_sensors_cover_the_run(record):
    """One rebound per lump, and the sensor streams cover the whole run on their grids."""
    ids = [lump.impact_id for lump in record.lumps if lump.contact_stamp_s < 3.9]
    rebound_ids = [i for i, _ in record.rebounds]
    assert set(ids) <= set(rebound_ids) and len(rebound_ids) == len(set(rebound_ids))
    assert record.pressure.stamp_s[0] == 0.0
    assert record.pressure.stamp_s[-1] == pytest.approx(4.0)
    assert np.all(np.diff(record.pressure.stamp_s) > 0)
    assert record.vibration.sample_count == pytest.approx(4.0 * 25600, abs=128)


def test_same_seed_same_record_whatever_the_step(record):
    """The same seed gives the same lumps and truths, and the same samples whatever the step
    (to rounding: the sensor stages' matrix products round by the number of samples asked)."""
    again = simulate_flow(params(**FAST_RISE), 4.0, seed=5, step_s=0.13)
    assert [t for _, t in again.truths] == [t for _, t in record.truths]
    assert again.lumps == record.lumps
    assert np.allclose(again.pressure.pressure_pa, record.pressure.pressure_pa, rtol=0, atol=1e-6)
    assert np.allclose(again.vibration.accel_mps2, record.vibration.accel_mps2, rtol=0, atol=1e-5)
    assert np.allclose(
        again.imu.linear_acceleration_mps2, record.imu.linear_acceleration_mps2, rtol=0, atol=1e-12
    )
    other = simulate_flow(params(**FAST_RISE), 1.0, seed=6)
    assert [lump.radius_m for lump in other.lumps[:5]] != [
        lump.radius_m for lump in record.lumps[:5]
    ]


def test_a_flow_without_the_accelerometer_keeps_the_other_samples(record):
    """``channels`` without the accelerometer: no vibration block, and the same jack pressure,
    IMU samples and truths as the run with every sensor (same seed, same step)."""
    lean = simulate_flow(params(**FAST_RISE), 4.0, seed=5, channels=("pressure", "imu"))
    assert lean.vibration.count == 0 and record.vibration.count > 0
    assert np.array_equal(lean.pressure.pressure_pa, record.pressure.pressure_pa)
    assert np.array_equal(lean.imu.linear_acceleration_mps2, record.imu.linear_acceleration_mps2)
    assert [t for _, t in lean.truths] == [t for _, t in record.truths]


def test_closed_window_brings_quiet_and_no_share_intervals():
    """No lump strikes after a window closes (plus the fall), and no interval is reported after."""
    run = simulate_flow(params(**FAST_RISE), 3.0, seed=1, windows=[(0.5, 1.2)])
    assert all(lump.contact_stamp_s <= 1.2 + 0.1 for lump in run.lumps)
    assert [s.start_stamp_s for s in run.shares] == [0.0, 1.0]
    assert run.windows == [(0.5, "open"), (1.2, "close")]


def test_windows_out_of_order_are_refused_by_name():
    """Windows that overlap or run backwards are refused naming windows[k]."""
    for windows in ([(1.0, 0.5)], [(0.0, 2.0), (1.0, 3.0)], [(0.0, math.inf), (5.0, 6.0)]):
        with pytest.raises(InputError) as error:
            simulate_flow(params(**FAST_RISE), 1.0, windows=windows)
        assert error.value.field.startswith("windows[")


def test_a_face_windows_flow_parameters_drive_the_flow():
    """The face model's window (tail_beam_sim.physics.face) hands its share curve and mass rate
    as flow parameters: they pass the flow's checks, and the lumps' gangue mass share follows
    the curve (pure coal before its first gangue)."""
    from tail_beam_sim.physics.face import (
        Face,
        FaceParams,
        Visit,
        close_at_true_share,
        draw_window,
        load_face_parameters,
    )

    face = Face(FaceParams.from_params(load_face_parameters()).with_changes(cell_size_m=0.25))
    window = draw_window(face, Visit(4, 0, None), close_at_true_share(0.5, 300.0)())
    flow = flow_params(**window.flow_parameters(300.0, 300.0))
    assert flow.rate_kind == "mass" and flow.mass_rate_kgps == 300.0
    seconds = window.mass_kg() / flow.mass_rate_kgps  # the whole window's draw
    lumps = lumps_of(flow, 0.0, seconds)
    # the curve is 0 up to the point before its first gangue share (linear from there)
    first_gangue = flow.share.drawn_mass_kg[np.argmax(flow.share.share > 0) - 1]
    early = [lump for lump in lumps if lump.drawn_mass_kg < first_gangue]
    assert early and not any(lump.is_gangue for lump in early)
    assert any(lump.is_gangue for lump in lumps)
