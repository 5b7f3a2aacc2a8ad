"""The beam's bending modes, read from how it rings after the impacts of its own recording.

A support's bending modes differ from config/'s (its beam section, its wear plates, where the
sensor is bolted), and they set how long the beam rings after an impact: the detector must not
take that ringing for new impacts (``identification.detection.ring_decay_s``). After each
impact, once the contact is over, the acceleration channel holds the free ring-down of every
mode the impact excited, each a decaying sinusoid exp(-zeta 2 pi f t) sin(2 pi f t ...). So,
with no labels and no model of the beam:

1. each impact's ring-down (from ``skip_s`` after its onset until the next impact or
   ``max_segment_s``) is freed of the beam's slow sway (a line removed, frequencies below
   ``min_frequency_hz`` left out) and its power spectrum taken; the spectra, each normalised
   to unit power so that large impacts do not drown the others, are summed, and the strongest
   peaks are the modes' frequencies;
2. for each peak, each ring-down is band-passed around it (zero phase) and its envelope
   (Hilbert) fitted by a straight line in log over the stretch where it stands clear of the
   channel's noise in that band: the slope is the decay rate sigma, and zeta = sigma / (2 pi f);
   the median over the impacts is the mode's damping.

What it gives is the coupled structure's modes as the sensor sees them (about 695 and 2226 Hz
on the nominal support, not modes.yaml's held modes at 344 and 2219 Hz), and no modal masses
(they need the force, which no sensor measures).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# ring-down starts this long after the onset (the longest contact, 1 ms, and the filter's delay), s
SKIP_S = 0.0015
MAX_SEGMENT_S = (
    0.25  # ring-down taken at most this long (a lightly damped 120 Hz mode rings for 0.3 s), s
)
MIN_SEGMENT_S = 0.01  # shorter ring-downs (the next impact came too soon) are not used, s
NEXT_IMPACT_MARGIN_S = 0.001  # a ring-down ends this long before the next impact's onset, s
MIN_FREQUENCY_HZ = (
    60.0  # modes are looked for above the beam's sway on the jack (nominal 39 Hz), Hz
)
NYQUIST_FRACTION = (
    0.4  # ... and below this fraction of the sample rate (the anti-alias filter), Hz per Hz
)
MAX_MODES = 3  # modes reported at the most: the strongest peaks
MIN_PEAK_PROMINENCE = 4.0  # a peak must stand this many times above the summed spectrum's median
MIN_OWN_PROMINENCE = (
    0.5  # ... and at least this fraction of its own height (twice the spectrum beside it)
)
MIN_IMPACTS = 3  # ring-downs needed
MAX_IMPACTS = (
    200  # ring-downs read at the most (a long recording's first ones): the cost stays bounded
)
BAND_FRACTION = 0.2  # half width of the band-pass around a mode, as a fraction of its frequency
MIN_PERIODS = 3.0  # a decay is fitted over at least this many periods of the mode
EDGE_PERIODS = 3.0  # periods of the mode left out at each end of a band-passed ring-down
NOISE_FLOOR = (
    3.0  # a ring-down is read while its envelope stands this many times over the band's noise
)
MIN_DECAY = (
    0.3  # ... and must fall by at least exp(-this) meanwhile (a steady tone is no ring-down)
)


@dataclass(frozen=True)
class RingingMode:
    """One mode as the recording shows it: frequency (Hz), damping ratio (1), and how many
    impacts' ring-downs gave the damping."""

    frequency_hz: float
    damping_ratio: float
    impacts: int

    @property
    def decay_time_s(self) -> float:
        """Time for the mode's amplitude to fall by e, s: 1 / (zeta 2 pi f)."""
        return 1.0 / (self.damping_ratio * 2.0 * math.pi * self.frequency_hz)


def ring_downs(
    stamp_s: np.ndarray,
    accel_mps2: np.ndarray,
    onsets_s: Sequence[float],
    skip_s: float = SKIP_S,
    max_segment_s: float = MAX_SEGMENT_S,
) -> list[np.ndarray]:
    """Each impact's ring-down: the samples from ``skip_s`` after its onset (s) to the next
    impact (less a margin) or ``max_segment_s``, with a line removed; ring-downs shorter than
    MIN_SEGMENT_S, or with a sample missing (a gap in the stamps), are left out."""
    stamp_s = np.asarray(stamp_s, dtype=float)
    accel_mps2 = np.asarray(accel_mps2, dtype=float)
    if stamp_s.size < 16:
        return []
    period = float(np.median(np.diff(stamp_s)))
    onsets = np.sort(np.asarray([t for t in onsets_s if math.isfinite(t)], dtype=float))
    segments = []
    for k, onset in enumerate(onsets):
        end = onset + max_segment_s
        if k + 1 < len(onsets):
            end = min(end, onsets[k + 1] - NEXT_IMPACT_MARGIN_S)
        if end - onset - skip_s < MIN_SEGMENT_S:
            continue
        lo, hi = np.searchsorted(stamp_s, [onset + skip_s, end])
        t, x = stamp_s[lo:hi], accel_mps2[lo:hi]
        if (
            t.size * period < 0.9 * MIN_SEGMENT_S
            or np.any(np.diff(t) > 1.5 * period)
            or not np.isfinite(x).all()
        ):
            continue
        segments.append(x - np.polyval(np.polyfit(t - t[0], x, 1), t - t[0]))
        if len(segments) >= MAX_IMPACTS:
            break
    return segments


def mode_frequencies(
    segments: Sequence[np.ndarray], period_s: float, min_frequency_hz: float = MIN_FREQUENCY_HZ
) -> list[float]:
    """The strongest peaks (Hz, at most MAX_MODES, ascending) of the ring-downs' summed
    normalised power spectra between ``min_frequency_hz`` and NYQUIST_FRACTION of the rate."""
    if len(segments) < MIN_IMPACTS:
        return []
    n = 1 << int(
        math.ceil(math.log2(8 * max(len(s) for s in segments)))
    )  # zero-padded: fine peak positions
    freq = np.fft.rfftfreq(n, period_s)
    total = np.zeros(freq.size)
    for s in segments:
        # Tapered at the end only (the right half of a Hann window): a ring-down is strongest at
        # its start, where a fast-decaying mode lives, and a full window would take it away.
        taper = np.cos(0.5 * np.pi * np.arange(len(s)) / len(s)) ** 2
        power = np.abs(np.fft.rfft(s * taper, n)) ** 2
        total += power / max(float(power.sum()), 1e-300)
    band = (freq >= min_frequency_hz) & (freq <= NYQUIST_FRACTION / period_s)
    if band.sum() < 8:
        return []
    spectrum = total[band]
    floor = float(np.median(spectrum))
    # scipy.signal is imported where used (a second or two to import: id_node's start need not
    # wait for it).
    from scipy.signal import find_peaks

    peaks, props = find_peaks(spectrum, prominence=MIN_PEAK_PROMINENCE * floor)
    # A mode stands out of what is around it: a ripple on the tail of a strong mode's peak (its
    # spectrum falls off as 1 / (f - f0)^2, far above the noise) does not.
    own = props["prominences"] >= MIN_OWN_PROMINENCE * spectrum[peaks]
    peaks, prominences = peaks[own], props["prominences"][own]
    strongest = peaks[np.argsort(prominences)[::-1][:MAX_MODES]]
    return sorted(float(freq[band][p]) for p in strongest)


def sample_noise(accel_mps2: np.ndarray) -> float:
    """The channel's white-noise RMS per sample (m/s^2), from the median absolute first
    difference: impacts and their ringing occupy little of a recording, and a bending mode
    moves little from one sample to the next, so the median sees the noise."""
    diff = np.diff(np.asarray(accel_mps2, dtype=float))
    return (
        float(1.4826 * np.median(np.abs(diff - np.median(diff))) / math.sqrt(2.0))
        if diff.size
        else 0.0
    )


def decay_rate(
    segment: np.ndarray, period_s: float, frequency_hz: float, noise_mps2: float
) -> float | None:
    """The decay rate (1/s) of the ring-down's component at ``frequency_hz``: the slope of its
    envelope (band-passed, Hilbert) in log, from its peak to where it sinks to NOISE_FLOOR times
    the band's noise (the channel's ``noise_mps2`` per sample, narrowed to the band); None
    where that stretch is shorter than MIN_PERIODS periods, or the mode does not decay."""
    rate = 1.0 / period_s
    low, high = (
        frequency_hz * (1.0 - BAND_FRACTION),
        min(frequency_hz * (1.0 + BAND_FRACTION), 0.49 * rate),
    )
    if not low < high:
        return None
    from scipy.signal import butter, hilbert, sosfiltfilt

    sos = butter(2, [low, high], btype="band", fs=rate, output="sos")
    edge = max(1, int(math.ceil(EDGE_PERIODS * rate / frequency_hz)))
    if len(segment) <= max(3 * 2 * sos.shape[0] + 1, 4 * edge):
        return None
    envelope = np.abs(hilbert(sosfiltfilt(sos, segment)))[edge:-edge]
    start = int(np.argmax(envelope[: max(envelope.size // 4, 1)]))  # from the envelope's peak on
    envelope = envelope[start:]
    # Narrowband noise's envelope has mean sigma sqrt(pi / 2), sigma^2 the noise power in the band.
    floor = noise_mps2 * math.sqrt((high - low) / (0.5 * rate)) * math.sqrt(math.pi / 2.0)
    below = np.flatnonzero(envelope < NOISE_FLOOR * floor)
    stop = int(below[0]) if below.size else envelope.size
    if stop * period_s < MIN_PERIODS / frequency_hz or stop < 4:
        return None
    t = np.arange(stop) * period_s
    sigma = -float(np.polyfit(t, np.log(envelope[:stop]), 1)[0])
    if not math.isfinite(sigma) or sigma * t[-1] < MIN_DECAY:
        return None  # a steady tone, or a mode too lightly damped to read in the segment
    return sigma


def ringing_modes(
    stamp_s: np.ndarray,
    accel_mps2: np.ndarray,
    onsets_s: Sequence[float],
    min_frequency_hz: float = MIN_FREQUENCY_HZ,
) -> list[RingingMode]:
    """The bending modes (ascending frequency) that the impacts at ``onsets_s`` (s) set ringing
    in the acceleration samples (``stamp_s`` s, ``accel_mps2`` m/s^2), each with its damping;
    a mode whose damping no ring-down gave is left out; [] with fewer than MIN_IMPACTS usable
    ring-downs."""
    stamp_s = np.asarray(stamp_s, dtype=float)
    segments = ring_downs(stamp_s, accel_mps2, onsets_s)
    if len(segments) < MIN_IMPACTS:
        return []
    period = float(np.median(np.diff(stamp_s)))
    noise = sample_noise(accel_mps2)
    modes = []
    for frequency in mode_frequencies(segments, period, min_frequency_hz):
        rates = [
            r for r in (decay_rate(s, period, frequency, noise) for s in segments) if r is not None
        ]
        if len(rates) >= MIN_IMPACTS:
            modes.append(
                RingingMode(
                    frequency, float(np.median(rates)) / (2.0 * math.pi * frequency), len(rates)
                )
            )
    return modes


def ring_decay_s(
    modes: Sequence[RingingMode], low_s: float = 0.002, high_s: float = 2.0
) -> float | None:
    """The detector's ``ring_decay_s`` for these modes (s): the slowest mode's decay time, so
    that the envelope it follows never dies away faster than the beam's ringing; None without
    modes."""
    if not modes:
        return None
    return float(min(max(max(m.decay_time_s for m in modes), low_s), high_s))
