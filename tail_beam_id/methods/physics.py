"""Physics-based identification: invert the impact model for what the particle must have been.

What the sensors observe of an impact (features.py): the moment impulse about the hinge
M = m v0 (1 + e) x, the rebound speed v1 = e v0, and the time from the onset to the camera's
end-of-contact stamp, i.e. the contact duration tc plus sensor lags. The Hertz contact gives
tc = 2.943 (5 pi rho / 4 E*)^0.4 R v0^-0.2 for an elastic sphere, lengthened by the hysteresis
damping by a factor that depends on e (tabulated from the project's own solver). Size, speed,
position and restitution trade off against material; each material hypothesis k (density,
contact modulus E*, restitution range) is weighed by how well some particle of that
material explains the observation: a Monte-Carlo bank of prior particles (radius, drop height,
restitution) per material, with the impact position marginalised in closed form. The result
is the posterior P(coal), and the posterior means of the particle's density, contact modulus,
restitution, radius and impact speed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import ndtr

from tail_beam_id.methods.base import Decision
from tail_beam_id.signals.features import VIBRATION_CHANNEL
from tail_beam_sim.errors import require_section
from tail_beam_sim.physics.contact import (
    effective_modulus_pa,
    hertz_constant,
    hertz_elastic_impact,
)
from tail_beam_sim.physics.materials import material_table, sphere_mass_kg
from tail_beam_sim.physics.support import Support
from tail_beam_sim.spec import Section, integer, number, of_kind, positive

LOG_IMPOSSIBLE = math.log(1e-100)  # log-likelihood of an observation a particle cannot give


DURATION_CACHE_SIZE = 8  # IMU periods whose per-particle duration terms are kept


_CAP = dict(low=0.5, high=1.0)

PHYSICS = Section(
    "identification.physics",
    "The physics method's inversion: priors and observation errors.",
    (
        of_kind(
            "pair", "prior_radius_m", "Prior radius range (log-uniform).", low=0.0, low_open=True
        ),
        of_kind("pair", "prior_drop_height_m", "Prior drop height range.", low=0.0, low_open=True),
        of_kind(
            "pair", "prior_position_m", "Prior impact position range.", low=0.0, low_open=True
        ),
        integer("prior_samples", "Prior particles per material.", 100, 10**6),
        integer("seed", "Seed of the prior.", default=0),
        number(
            "moment_model_error", "Relative error of the rigid-beam moment impulse.", "", 0.0, 1.0
        ),
        number(
            "duration_model_error", "Relative error of the Hertz contact duration.", "", 0.0, 1.0
        ),
        positive("rebound_noise_mps", "Camera rebound-velocity noise RMS.", "m/s"),
        number("rebound_noise_fraction", "... plus this fraction of the reading.", "", 0.0, 1.0),
        number(
            "outlier_log_likelihood", "Below this no particle explains the impact.", "", None, 0.0
        ),
        number("outlier_confidence_cap", "Confidence cap of such an impact.", **_CAP),
    ),
    file="identification.yaml",
)


@dataclass(frozen=True)
class PhysicsConfig:
    """Priors (m, m, m) and observation-model errors of the inversion (identification.physics)."""

    prior_radius_m: tuple[float, float]
    prior_drop_height_m: tuple[float, float]
    prior_position_m: tuple[float, float]
    prior_samples: int
    seed: int
    moment_model_error: float
    duration_model_error: float
    rebound_noise_mps: float
    rebound_noise_fraction: float
    outlier_log_likelihood: float
    outlier_confidence_cap: float

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> PhysicsConfig:
        return cls(**PHYSICS.check(params or {}))


@dataclass(frozen=True)
class PriorBank:
    """Prior particles of every candidate material, as flat arrays over all samples."""

    material: np.ndarray  # index into names
    names: tuple[str, ...]
    is_coal: np.ndarray
    log_prior: np.ndarray  # log prior probability of each sample's material, per sample
    density_kgpm3: np.ndarray
    modulus_pa: np.ndarray  # contact modulus E* with the plate
    radius_m: np.ndarray
    speed_mps: np.ndarray
    restitution: np.ndarray
    impulse_ns: np.ndarray  # J = m v0 (1 + e)
    log_impulse_span: np.ndarray  # log(J (x_max - x_min)): the moment range a particle can give
    duration_s: np.ndarray


def duration_ratio(restitution: np.ndarray, table: Mapping[str, Any]) -> np.ndarray:
    """Contact duration with hysteresis damping over the elastic one, from the solver's table."""
    return np.interp(restitution, table["restitution"], table["ratio"])


def build_bank(
    config: PhysicsConfig, params: Mapping[str, Any], ratio_table: Mapping[str, Any]
) -> PriorBank:
    """Draw the prior particles (seeded): equal coal and gangue odds, gangue materials equal."""
    materials = material_table(params)
    support = Support.from_params(params["support"], materials)
    names = tuple(
        sorted(n for n, m in materials.items() if m.material_class in ("coal", "gangue"))
    )
    coal = [n for n in names if materials[n].is_coal]
    gangue = [n for n in names if not materials[n].is_coal]
    rng = np.random.default_rng(config.seed)
    n = config.prior_samples
    columns: dict[str, list[np.ndarray]] = {
        k: [] for k in ("material", "log_prior", "rho", "estar", "r", "v", "e")
    }
    for index, name in enumerate(names):
        m = materials[name]
        share = 0.5 / len(coal) if m.is_coal else 0.5 / max(len(gangue), 1)
        low, high = config.prior_radius_m
        radius = np.exp(rng.uniform(math.log(low), math.log(high), n))
        height = rng.uniform(*config.prior_drop_height_m, n)
        e = rng.uniform(*m.restitution_range, n)
        columns["material"].append(np.full(n, index))
        columns["log_prior"].append(np.full(n, math.log(share)))
        columns["rho"].append(np.full(n, m.density_kgpm3))
        columns["estar"].append(np.full(n, effective_modulus_pa(m, support.plate)))
        columns["r"].append(radius)
        columns["v"].append(np.sqrt(2.0 * support.gravity_mps2 * height))
        columns["e"].append(e)
    cat = {k: np.concatenate(v) for k, v in columns.items()}
    mass = sphere_mass_kg(cat["rho"], cat["r"])
    elastic = hertz_elastic_impact(hertz_constant(cat["estar"], cat["r"]), mass, cat["v"])
    duration = elastic["duration_s"] * duration_ratio(cat["e"], ratio_table)
    return PriorBank(
        material=cat["material"].astype(int),
        names=names,
        is_coal=np.array([materials[names[i]].is_coal for i in cat["material"].astype(int)]),
        log_prior=cat["log_prior"],
        density_kgpm3=cat["rho"],
        modulus_pa=cat["estar"],
        radius_m=cat["r"],
        speed_mps=cat["v"],
        restitution=cat["e"],
        impulse_ns=mass * cat["v"] * (1.0 + cat["e"]),
        log_impulse_span=np.log(
            mass
            * cat["v"]
            * (1.0 + cat["e"])
            * (config.prior_position_m[1] - config.prior_position_m[0])
        ),
        duration_s=duration,
    )


class PhysicsMethod:
    """Bayesian inversion of the impact model over a bank of prior particles."""

    name = "physics"

    def __init__(
        self,
        config: PhysicsConfig,
        bank: PriorBank,
        timing: list[Mapping[str, float]],
        timing_vibration: list[Mapping[str, float]] | None = None,
    ) -> None:
        self.config = config
        self.bank = bank
        self.timing = sorted(timing, key=lambda t: t["imu_period_s"])
        # The lag when the accelerometer is the channel (its anti-alias filter delays the onset);
        # the IMU's when the model file has none.
        self.timing_vibration = (
            sorted(timing_vibration, key=lambda t: t["imu_period_s"])
            if timing_vibration
            else self.timing
        )
        self.rebound_speed_mps = bank.restitution * bank.speed_mps
        self._duration_terms: dict[
            tuple[bool, float], tuple[np.ndarray, np.ndarray, np.ndarray]
        ] = {}

    @classmethod
    def from_model(cls, model: Mapping[str, Any], params: Mapping[str, Any]) -> PhysicsMethod:
        config = PhysicsConfig.from_params(
            require_section("identification.physics", params["identification"].get("physics"))
        )
        return cls(
            config,
            build_bank(config, params, model["duration_ratio"]),
            model["timing"],
            model.get("timing_vibration"),
        )

    def _lag(self, period_s: float, vibration: bool = False) -> Mapping[str, float]:
        """The camera-minus-onset lag model at this IMU (or, with ``vibration``, accelerometer)
        period: interpolated in log(period) between the measured bands (any rate, never a
        category; held at the end bands)."""
        table = self.timing_vibration if vibration else self.timing
        log_p = [math.log(t["imu_period_s"]) for t in table]
        x = math.log(period_s)
        return {
            "imu_period_s": period_s,
            "mean_s": float(np.interp(x, log_p, [t["mean_s"] for t in table])),
            "std_s": float(np.interp(x, log_p, [t["std_s"] for t in table])),
        }

    def _duration_model(
        self, period_s: float, vibration: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per prior particle: expected camera-minus-onset delay (s), 1 / its spread (1/s) and
        that reciprocal's log, for the channel's lag model at this period (cached per period)."""
        lag = self._lag(period_s, vibration)
        key = (vibration, round(period_s, 9))
        if key not in self._duration_terms and len(self._duration_terms) >= DURATION_CACHE_SIZE:
            self._duration_terms.pop(
                next(iter(self._duration_terms))
            )  # one support streams at one rate: keep a few
        if key not in self._duration_terms:
            b = self.bank
            sigma = np.hypot(lag["std_s"], self.config.duration_model_error * b.duration_s)
            self._duration_terms[key] = (b.duration_s + lag["mean_s"], 1.0 / sigma, -np.log(sigma))
        return self._duration_terms[key]

    def log_likelihood(self, features: Mapping[str, float]) -> np.ndarray:
        """log p(observation | each prior particle), position marginalised."""
        b, c = self.bank, self.config
        log_l = np.zeros(b.impulse_ns.size)
        moment = features.get("moment_impulse_nms")
        if moment is not None:
            sigma = math.hypot(
                features.get("moment_impulse_sigma_nms", 0.0), c.moment_model_error * abs(moment)
            )
            low, high = c.prior_position_m
            upper = (b.impulse_ns * high - moment) / sigma
            lower = (b.impulse_ns * low - moment) / sigma
            # P(some position in the prior range gives this moment): 1 or 0 except near an edge.
            log_mass = np.where((upper > 0.0) & (lower < 0.0), 0.0, LOG_IMPOSSIBLE)
            edge = (np.abs(upper) < 8.0) | (np.abs(lower) < 8.0)
            log_mass[edge] = np.log(np.maximum(ndtr(upper[edge]) - ndtr(lower[edge]), 1e-100))
            log_l += log_mass - b.log_impulse_span
        speed = features.get("rebound_speed_mps")
        if speed is not None:
            sigma = math.hypot(
                c.rebound_noise_mps + c.rebound_noise_fraction * abs(speed),
                features.get("rebound_cross_mps", 0.0),
            )
            log_l += -0.5 * ((speed - self.rebound_speed_mps) / sigma) ** 2 - math.log(sigma)
        delay = features.get("rebound_delay_s")
        if delay is not None and "imu_period_s" in features:
            expected, inverse_sigma, log_inverse_sigma = self._duration_model(
                features["imu_period_s"], bool(features.get(VIBRATION_CHANNEL))
            )
            log_l += log_inverse_sigma - 0.5 * ((delay - expected) * inverse_sigma) ** 2
        return log_l

    def decide(self, features: Mapping[str, float]) -> Decision:
        b = self.bank
        log_l = self.log_likelihood(features)
        log_post = log_l + b.log_prior
        relative = log_post - np.max(log_post)
        # Particles more than e^-50 less likely than the best weigh nothing (and would only
        # slow the arithmetic down as subnormal numbers).
        weights = np.where(relative > -50.0, np.exp(np.maximum(relative, -50.0)), 0.0)
        weights /= weights.sum()
        p_coal = float(np.sum(weights[b.is_coal]))
        # Element-wise sums, not BLAS dot products: cheaper for one vector on a busy machine.
        estimates = {
            "estimated_density_kgpm3": float(np.sum(weights * b.density_kgpm3)),
            "estimated_contact_modulus_pa": float(np.sum(weights * b.modulus_pa)),
            "estimated_restitution": float(np.sum(weights * b.restitution)),
            "estimated_radius_m": float(np.sum(weights * b.radius_m)),
            "estimated_impact_speed_mps": float(np.sum(weights * b.speed_mps)),
            "best_log_likelihood": float(np.max(log_l)),
        }
        # No particle of any material explains the observation: the model does not hold here.
        if self._outlier(features, log_l):
            cap = self.config.outlier_confidence_cap
            p_coal = min(max(p_coal, 1.0 - cap), cap)
            estimates["outlier"] = 1.0
        return Decision(min(max(p_coal, 1e-6), 1.0 - 1e-6), estimates)

    def _outlier(self, features: Mapping[str, float], log_l: np.ndarray) -> bool:
        """True when even the best prior particle is further than the configured likelihood
        from the observation (relative to a perfect fit of each observed quantity)."""
        best = self.log_likelihood_at_perfect_fit(features)
        return float(np.max(log_l)) - best < self.config.outlier_log_likelihood

    def log_likelihood_at_perfect_fit(self, features: Mapping[str, float]) -> float:
        """The Gaussian terms' log-likelihood if every prediction matched exactly (reference)."""
        c = self.config
        best = 0.0
        speed = features.get("rebound_speed_mps")
        if speed is not None:
            best -= math.log(
                math.hypot(
                    c.rebound_noise_mps + c.rebound_noise_fraction * abs(speed),
                    features.get("rebound_cross_mps", 0.0),
                )
            )
        delay = features.get("rebound_delay_s")
        if delay is not None and "imu_period_s" in features:
            lag = self._lag(features["imu_period_s"], bool(features.get(VIBRATION_CHANNEL)))
            best -= math.log(
                math.hypot(lag["std_s"], c.duration_model_error * max(delay - lag["mean_s"], 1e-5))
            )
        moment = features.get("moment_impulse_nms")
        if moment is not None:
            low, high = c.prior_position_m
            best -= math.log(max(abs(moment), 1e-9) / (0.5 * (low + high)) * (high - low))
        return best
