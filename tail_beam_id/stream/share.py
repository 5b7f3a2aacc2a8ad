"""The gangue share of a caving flow over a sliding interval: how much of what strikes the tail
beam is rock, read from the labels where the impacts can be told apart and from the beam's
vibration statistics where they cannot (docs/gangue_share.md).

Basis: the share by count, the fraction of the lumps striking in the interval that are gangue.

* Separable impacts (few of the interval's labels overlap another impact): the share is the
  fraction of labels that say gangue, with its Wilson 95 % interval (``basis_method: labels``).
* Dense flow (responses overlap: per-impact labels fall to chance): the share is a linear
  model of the acceleration channel's statistics per frame, averaged over the interval: the
  energy in octave-like bands, the kurtosis and the spectral centroid (gangue is stiffer, its
  contacts are shorter and excite higher bands), trained on simulated flows across drawn
  supports (``tail_beam_id/models/gangue_share.json``); its 95 % interval is the share plus or
  minus 1.96 held-out residual standard deviations (``basis_method: vibration``).

Everything here depends on stamps and sample values only: frames are fixed on the stamp grid
(``k frame_s``), intervals end on the grid ``k hop_s``, so live (id_node) and offline (tail-beam
identify) give the same shares.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tail_beam_id.stream.label import Label
from tail_beam_sim.errors import InputError
from tail_beam_sim.spec import Section, integer, number, positive

BASIS = "count"  # the share is the fraction of lumps that are gangue, by number
Z_95 = 1.959963984540054  # two-sided 95 % normal quantile
MODEL_PATH = Path(__file__).resolve().parent.parent / "models" / "gangue_share.json"
# Band edges of the frame statistics, Hz; each band is kept below 0.45 x the channel's rate.
BAND_EDGES_HZ = (100.0, 400.0, 1000.0, 2500.0, 5000.0, 11000.0)
MIN_CENTROID_HZ = 100.0  # the spectral centroid leaves out the beam's sway below this, Hz

GANGUE_SHARE = Section(
    "identification.gangue_share",
    "The gangue share of the flow over a sliding interval (topic gangue_share).",
    (
        positive("interval_s", "Length of each interval.", "s", high=60.0, default=1.0),
        positive("hop_s", "A new interval ends every this long.", "s", high=60.0, default=0.5),
        positive(
            "frame_s",
            "Vibration statistics are read per frame of this length.",
            "s",
            high=1.0,
            default=0.1,
        ),
        positive(
            "settle_s",
            "An interval is published once every live stream is this far past its end and no "
            "impact before its end waits for a decision.",
            "s",
            high=10.0,
            default=0.1,
        ),
        number(
            "max_overlap_fraction",
            "Above this fraction of overlapping labels the vibration model decides, not labels.",
            "",
            0.0,
            1.0,
            default=0.25,
        ),
        integer(
            "min_labels",
            "Fewer labels in an interval: the vibration model decides.",
            0,
            1000,
            default=1,
        ),
        number(
            "min_frame_fill",
            "A frame with fewer than this fraction of its expected samples is left out.",
            "",
            0.0,
            1.0,
            default=0.5,
        ),
    ),
)


@dataclass(frozen=True)
class ShareConfig:
    """The ``identification.gangue_share`` section, validated (times in s)."""

    interval_s: float = 1.0
    hop_s: float = 0.5
    frame_s: float = 0.1
    settle_s: float = 0.1
    max_overlap_fraction: float = 0.25
    min_labels: int = 1
    min_frame_fill: float = 0.5

    @classmethod
    def from_params(cls, section: Mapping[str, Any] | None) -> ShareConfig:
        checked = cls(**GANGUE_SHARE.check(section or {}))
        for name in ("interval_s", "hop_s"):
            steps = getattr(checked, name) / checked.frame_s
            if abs(steps - round(steps)) > 1e-9:
                raise InputError(
                    f"identification.gangue_share.{name}",
                    getattr(checked, name),
                    f"must be a whole number of frame_s ({checked.frame_s:g} s)",
                )
        return checked


def wilson_interval(successes: int, total: int, z: float = Z_95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (two-sided, ``z`` normal quantiles)."""
    if total < 0 or not 0 <= successes <= total:
        raise InputError("successes", successes, f"must be in [0, total = {total}]")
    if total == 0:
        return 0.0, 1.0
    p = successes / total
    denom = 1.0 + z * z / total
    centre = (p + z * z / (2 * total)) / denom
    half = z * math.sqrt(p * (1 - p) / total + z * z / (4 * total * total)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass(frozen=True)
class GangueShare:
    """One interval's estimate: the share (0..1, None when nothing struck and the vibration
    says nothing), its 95 % interval and standard error, on what it rests."""

    start_stamp_s: float
    end_stamp_s: float
    share: float | None
    low: float
    high: float
    standard_error: float | None
    lumps: int  # labels (impacts identified) in the interval
    gangue_lumps: int  # of those, labelled gangue
    overlapping: int  # of those, overlapping another impact
    basis_method: str  # labels | vibration | none
    signals: tuple[str, ...]
    basis: str = BASIS

    def to_json(self) -> str:
        return json.dumps(
            {
                "start_stamp_s": self.start_stamp_s,
                "end_stamp_s": self.end_stamp_s,
                "share": self.share,
                "basis": self.basis,
                "low": self.low,
                "high": self.high,
                "standard_error": self.standard_error,
                "lumps": self.lumps,
                "gangue_lumps": self.gangue_lumps,
                "overlapping": self.overlapping,
                "method": self.basis_method,
                "signals": list(self.signals),
            },
            sort_keys=True,
        )

    @classmethod
    def from_json(cls, text: str) -> GangueShare:
        """Decode a ``gangue_share`` message; anything else raises InputError naming the field."""
        try:
            data = json.loads(text)
        except (TypeError, ValueError) as exc:
            raise InputError("gangue_share", str(text)[:60], f"must be JSON ({exc})") from None
        if not isinstance(data, dict):
            raise InputError("gangue_share", str(text)[:60], "must be a JSON object")
        try:
            share = data["share"]
            if share is not None and not 0.0 <= float(share) <= 1.0:
                raise InputError("gangue_share.share", share, "must be in [0, 1] or null")
            return cls(
                float(data["start_stamp_s"]),
                float(data["end_stamp_s"]),
                None if share is None else float(share),
                float(data["low"]),
                float(data["high"]),
                None if data["standard_error"] is None else float(data["standard_error"]),
                int(data["lumps"]),
                int(data["gangue_lumps"]),
                int(data["overlapping"]),
                str(data["method"]),
                tuple(str(s) for s in data["signals"]),
                str(data["basis"]),
            )
        except KeyError as exc:
            raise InputError(f"gangue_share.{exc.args[0]}", None, "missing") from None
        except (TypeError, ValueError) as exc:
            raise InputError("gangue_share", str(text)[:60], f"a field of the wrong type ({exc})")


def frame_statistics(accel_mps2: np.ndarray, rate_hz: float) -> np.ndarray:
    """The statistics of one frame of the acceleration channel (samples m/s^2 at ``rate_hz``):
    log10 of the share of the energy above MIN_CENTROID_HZ in each band of BAND_EDGES_HZ below
    0.45 x the rate (bands beyond it: -6), log10 of the spectral centroid (Hz) above
    MIN_CENTROID_HZ, log10 of the kurtosis, log10 of the rms above MIN_CENTROID_HZ (m/s^2)."""
    x = np.asarray(accel_mps2, dtype=float)
    if x.size < 8 or not rate_hz > 0.0:
        raise InputError("frame", x.size, "must hold at least 8 samples at a positive rate")
    x = x - x.mean()
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    freqs = np.fft.rfftfreq(x.size, 1.0 / rate_hz)
    above = freqs >= MIN_CENTROID_HZ
    total = float(spectrum[above].sum()) + 1e-30
    bands = []
    for low, high in zip(BAND_EDGES_HZ[:-1], BAND_EDGES_HZ[1:]):
        if low >= 0.45 * rate_hz:
            bands.append(-6.0)
            continue
        inside = (freqs >= low) & (freqs < min(high, 0.45 * rate_hz))
        bands.append(math.log10(float(spectrum[inside].sum()) / total + 1e-6))
    centroid = float((freqs[above] * spectrum[above]).sum()) / total
    centred = x - x.mean()
    var = float(np.mean(centred**2)) + 1e-30
    kurtosis = float(np.mean(centred**4)) / var**2
    rms = math.sqrt(total / max(1.0, float(np.sum(np.hanning(x.size) ** 2))) / x.size * 2.0)
    return np.array(
        [*bands, math.log10(max(centroid, 1.0)), math.log10(kurtosis), math.log10(rms + 1e-9)]
    )


@dataclass
class FrameAccumulator:
    """Samples of the acceleration channel gathered into frames ``[k frame_s, (k+1) frame_s)``
    of stamp time; a frame's statistics are taken once a later sample has come (or at the end
    of the data), from the samples it holds, when they fill at least ``min_fill`` of it."""

    frame_s: float
    min_fill: float
    channel: str
    frames: dict[int, np.ndarray] = field(default_factory=dict)  # k -> statistics
    _k: int | None = None
    _stamps: list[np.ndarray] = field(default_factory=list)
    _values: list[np.ndarray] = field(default_factory=list)

    def add(self, stamp_s: np.ndarray, accel_mps2: np.ndarray) -> None:
        """Samples in stamp order (s, m/s^2); non-finite ones are left out."""
        t = np.asarray(stamp_s, dtype=float).ravel()
        v = np.asarray(accel_mps2, dtype=float).ravel()
        ok = np.isfinite(t) & np.isfinite(v)
        t, v = t[ok], v[ok]
        if not t.size:
            return
        ks = np.floor(t / self.frame_s + 1e-9).astype(np.int64)
        start = 0
        while start < t.size:
            k = int(ks[start])
            end = start + int(np.searchsorted(ks[start:], k, side="right"))
            if self._k is not None and k != self._k:
                self.close()
            if self._k is None or k >= self._k:
                self._k = k
                self._stamps.append(t[start:end])
                self._values.append(v[start:end])
            start = end

    def close(self) -> None:
        """Take the statistics of the frame being gathered (end of data, or a later sample)."""
        if self._k is None:
            return
        t = np.concatenate(self._stamps)
        v = np.concatenate(self._values)
        k, self._k, self._stamps, self._values = self._k, None, [], []
        if t.size < 8:
            return
        period = float(np.median(np.diff(t)))
        if not period > 0.0:
            return
        if t.size < self.min_fill * self.frame_s / period:
            return
        self.frames[k] = frame_statistics(v, 1.0 / period)

    def newest_frame(self) -> int | None:
        """The frame being gathered (its statistics are not taken yet)."""
        return self._k


@dataclass(frozen=True)
class ShareModel:
    """The vibration model of one acceleration channel: share = clip(w . z + b, 0, 1) with z
    the interval's mean frame statistics standardised (``mean``, ``scale``), its residual
    standard deviation on held-out flows."""

    channel: str
    mean: np.ndarray
    scale: np.ndarray
    weights: np.ndarray
    bias: float
    residual_sd: float

    def predict(self, stats: np.ndarray) -> float:
        z = (np.asarray(stats, dtype=float) - self.mean) / self.scale
        return float(np.clip(z @ self.weights + self.bias, 0.0, 1.0))

    def as_dict(self) -> dict[str, Any]:
        return {
            "mean": self.mean.tolist(),
            "scale": self.scale.tolist(),
            "weights": self.weights.tolist(),
            "bias": self.bias,
            "residual_sd": self.residual_sd,
        }

    @classmethod
    def from_dict(cls, channel: str, data: Mapping[str, Any]) -> ShareModel:
        model = cls(
            channel,
            np.asarray(data["mean"], dtype=float),
            np.asarray(data["scale"], dtype=float),
            np.asarray(data["weights"], dtype=float),
            float(data["bias"]),
            float(data["residual_sd"]),
        )
        if not model.mean.shape == model.scale.shape == model.weights.shape:
            raise InputError(f"gangue_share model {channel}", model.mean.shape, "shapes differ")
        return model


def load_share_models(path: str | Path | None = None) -> dict[str, ShareModel]:
    """The vibration models by channel (``vibration``, ``imu``); {} when the file is absent."""
    where = Path(path) if path is not None else MODEL_PATH
    if not where.exists():
        return {}
    data = json.loads(where.read_text())
    return {name: ShareModel.from_dict(name, entry) for name, entry in data["channels"].items()}


def interval_statistics(frames: Mapping[int, np.ndarray], first: int, count: int) -> np.ndarray:
    """The mean statistics of frames ``first .. first + count - 1`` that were taken (empty when
    none was)."""
    taken = [frames[k] for k in range(first, first + count) if k in frames]
    return np.mean(taken, axis=0) if taken else np.zeros(0)


def estimate_share(
    labels: Sequence[Label],
    start_s: float,
    end_s: float,
    config: ShareConfig,
    stats: np.ndarray | None = None,
    model: ShareModel | None = None,
) -> GangueShare:
    """The share over [start_s, end_s) from the labels whose impact lies in it and, when they
    are too few or overlap too much, from the interval's vibration statistics (``stats``)
    through ``model``."""
    if not end_s > start_s:
        raise InputError("end_stamp_s", end_s, f"must be after start_stamp_s ({start_s})")
    inside = [lab for lab in labels if start_s <= lab.impact_stamp_s < end_s]
    n = len(inside)
    k = sum(lab.material == "gangue" for lab in inside)
    overlapping = sum(bool(lab.overlap) for lab in inside)
    label_signals = tuple(sorted({s for lab in inside for s in lab.signals}))
    separable = n >= max(1, config.min_labels) and overlapping <= config.max_overlap_fraction * n
    usable_model = model is not None and stats is not None and stats.size == model.mean.size
    if separable or (not usable_model and n):
        low, high = wilson_interval(k, n)
        p = k / n
        return GangueShare(
            start_s,
            end_s,
            p,
            low,
            high,
            math.sqrt(p * (1 - p) / n),
            n,
            k,
            overlapping,
            "labels",
            label_signals,
        )
    if usable_model:
        assert model is not None and stats is not None
        p = model.predict(stats)
        half = Z_95 * model.residual_sd
        return GangueShare(
            start_s,
            end_s,
            p,
            max(0.0, p - half),
            min(1.0, p + half),
            model.residual_sd,
            n,
            k,
            overlapping,
            "vibration",
            (model.channel,),
        )
    return GangueShare(start_s, end_s, None, 0.0, 1.0, None, 0, 0, 0, "none", ())


def interval_ends(first_s: float, last_s: float, config: ShareConfig) -> list[float]:
    """Ends ``k hop_s`` of every interval that lies wholly in [first_s, last_s] (s)."""
    if not (math.isfinite(first_s) and math.isfinite(last_s)):
        return []
    k0 = math.ceil((first_s + config.interval_s) / config.hop_s - 1e-9)
    k1 = math.floor(last_s / config.hop_s + 1e-9)
    return [k * config.hop_s for k in range(k0, k1 + 1)]
