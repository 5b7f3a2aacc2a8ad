"""A :class:`StreamIdentifier` that also reads the gangue share of the flow
(:mod:`tail_beam_id.stream.share`): the same labels, and one :class:`GangueShare` per sliding
interval once the interval is settled.

An interval ``[end - interval_s, end)`` is settled when every live continuous stream has passed
``end + settle_s`` and no impact found before ``end`` waits for its decision (or at the end of
the data, for every interval the data covers). Its estimate rests on the labels of the impacts
in it and the acceleration channel's frames in it (the accelerometer's when it delivered any of
them, else the IMU's): both depend on stamps and samples only, so id_node (fed by its arrival
gate) and tail-beam identify (fed by replay) publish the same shares.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import (
    FrameAccumulator,
    GangueShare,
    ShareConfig,
    ShareModel,
    estimate_share,
    interval_ends,
    interval_statistics,
    load_share_models,
)


class SharingIdentifier(StreamIdentifier):
    """Labels each impact (as :class:`StreamIdentifier`) and reads the flow's gangue share;
    :meth:`take_shares` hands out the intervals settled so far, in stamp order."""

    def __init__(
        self,
        *args: Any,
        share_models: Mapping[str, ShareModel] | None = None,
        **kwargs: Any,
    ) -> None:
        """Arguments as :class:`StreamIdentifier`; ``share_models``: the vibration models by
        channel (None: the shipped ``models/gangue_share.json``)."""
        super().__init__(*args, **kwargs)
        params = kwargs.get("params")
        section = (params or {}).get("gangue_share") if params is not None else None
        self.share_config = ShareConfig.from_params(section)
        self.share_models = dict(load_share_models() if share_models is None else share_models)
        cfg = self.share_config
        self._frames = {
            "vibration": FrameAccumulator(cfg.frame_s, cfg.min_frame_fill, "vibration"),
            "imu": FrameAccumulator(cfg.frame_s, cfg.min_frame_fill, "imu"),
        }
        self._labels: list[Label] = []
        self._first_s = math.inf
        self._emitted_end_s = -math.inf
        self._settled: list[GangueShare] = []

    # ---- input -------------------------------------------------------------------------------
    def _first(self, stamp_s: np.ndarray) -> None:
        stamps = np.asarray(stamp_s, dtype=float)
        finite = stamps[np.isfinite(stamps)]
        if finite.size:
            self._first_s = min(self._first_s, float(finite.min()))

    def add_pressure(self, stamp_s: np.ndarray, pressure_pa: np.ndarray) -> None:
        self._first(np.atleast_1d(stamp_s))
        super().add_pressure(stamp_s, pressure_pa)

    def add_imu(
        self,
        stamp_s: np.ndarray,
        angular_velocity_radps: np.ndarray,
        linear_acceleration_mps2: np.ndarray,
    ) -> None:
        stamps = np.atleast_1d(np.asarray(stamp_s, dtype=float))
        self._first(stamps)
        accel = np.asarray(linear_acceleration_mps2, dtype=float).reshape(-1, 3)
        if accel.shape[0] == stamps.size:
            self._frames["imu"].add(stamps, accel[:, 2])
        super().add_imu(stamp_s, angular_velocity_radps, linear_acceleration_mps2)

    def add_vibration(self, stamp_s: np.ndarray, accel_mps2: np.ndarray) -> None:
        stamps = np.atleast_1d(np.asarray(stamp_s, dtype=float))
        self._first(stamps)
        values = np.atleast_1d(np.asarray(accel_mps2, dtype=float)).ravel()
        if values.size == stamps.size:
            self._frames["vibration"].add(stamps, values)
        super().add_vibration(stamp_s, accel_mps2)

    # ---- output ------------------------------------------------------------------------------
    def poll(self) -> list[Label]:
        labels = super().poll()
        self._labels += labels
        self._settle(self._settled_s())
        return labels

    def flush(self) -> list[Label]:
        labels = super().flush()
        self._labels += labels
        for frames in self._frames.values():
            frames.close()
        self._settle(self.channels.newest_s())
        return labels

    def take_shares(self) -> list[GangueShare]:
        """The intervals settled since the last call, in stamp order."""
        out, self._settled = self._settled, []
        return out

    def _settled_s(self) -> float:
        """Stamp up to which every interval can be estimated for good, s (module docstring)."""
        live = [s.latest_s for s in self.channels.continuous() if self.channels.live(s, False)]
        if not live:
            return -math.inf
        settled = min(live) - self.share_config.settle_s
        if self.impacts.pending:
            settled = min(settled, min(i.onset_s for i in self.impacts.pending))
        return settled

    def _settle(self, settled_s: float) -> None:
        cfg = self.share_config
        for end in interval_ends(self._first_s, settled_s, cfg):
            if end <= self._emitted_end_s + 1e-9:
                continue
            start = end - cfg.interval_s
            first = round(start / cfg.frame_s)
            count = round(cfg.interval_s / cfg.frame_s)
            stats, model = np.zeros(0), None
            for channel in ("vibration", "imu"):
                stats = interval_statistics(self._frames[channel].frames, first, count)
                if stats.size:
                    model = self.share_models.get(channel)
                    break
            self._settled.append(estimate_share(self._labels, start, end, cfg, stats, model))
            self._emitted_end_s = end
        self._forget(self._emitted_end_s + cfg.hop_s - cfg.interval_s)

    def _forget(self, oldest_s: float) -> None:
        """Drop labels and frames no later interval can need (before ``oldest_s``, s)."""
        if not math.isfinite(oldest_s):
            return
        self._labels = [lab for lab in self._labels if lab.impact_stamp_s >= oldest_s - 1e-9]
        oldest_k = math.floor(oldest_s / self.share_config.frame_s + 1e-9)
        for frames in self._frames.values():
            for k in [k for k in frames.frames if k < oldest_k]:
                del frames.frames[k]
