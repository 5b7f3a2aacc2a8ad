"""A :class:`StreamIdentifier` that also reads the gangue share of the flow
(:mod:`tail_beam_id.stream.share`): the same labels, and one :class:`GangueShare` per sliding
interval once the interval is settled.

An interval ``[end - interval_s, end)`` is settled when every live continuous stream has passed
``end + settle_s`` and no impact found before ``end`` waits for its decision (or, at the end of
the data, for every interval the data covers). Its estimate rests on the labels of the impacts
in it, which depend on stamps and samples only, so id_node (fed by its arrival gate) and
tail-beam identify (fed by replay) publish the same shares.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import Label
from tail_beam_id.stream.share import (
    GangueShare,
    ScoreModel,
    ShareConfig,
    estimate_share,
    interval_ends,
    load_score_model,
)

_SHIPPED = object()  # share_model not given: the shipped models/gangue_share.json


class SharingIdentifier(StreamIdentifier):
    """Labels each impact (as :class:`StreamIdentifier`) and reads the flow's gangue share;
    :meth:`take_shares` hands out the intervals settled so far, in stamp order."""

    def __init__(self, *args: Any, share_model: Any = _SHIPPED, **kwargs: Any) -> None:
        """Arguments as :class:`StreamIdentifier`; ``share_model``: the
        :class:`~tail_beam_id.stream.share.ScoreModel` for dense flows (None: labels only;
        default: the shipped one)."""
        super().__init__(*args, **kwargs)
        params = kwargs.get("params")
        self.share_config = ShareConfig.from_params((params or {}).get("gangue_share"))
        self.share_model: ScoreModel | None = (
            load_score_model() if share_model is _SHIPPED else share_model
        )
        self._labels: list[Label] = []
        self._first_s = math.inf
        self._emitted_end_s = -math.inf
        self._settled: list[GangueShare] = []

    # ---- input -------------------------------------------------------------------------------
    def _first(self, stamp_s: Any) -> None:
        stamps = np.atleast_1d(np.asarray(stamp_s, dtype=float))
        finite = stamps[np.isfinite(stamps)]
        if finite.size:
            self._first_s = min(self._first_s, float(finite.min()))

    def add_pressure(self, stamp_s: np.ndarray, pressure_pa: np.ndarray) -> None:
        self._first(stamp_s)
        super().add_pressure(stamp_s, pressure_pa)

    def add_imu(
        self,
        stamp_s: np.ndarray,
        angular_velocity_radps: np.ndarray,
        linear_acceleration_mps2: np.ndarray,
    ) -> None:
        self._first(stamp_s)
        super().add_imu(stamp_s, angular_velocity_radps, linear_acceleration_mps2)

    def add_vibration(self, stamp_s: np.ndarray, accel_mps2: np.ndarray) -> None:
        self._first(stamp_s)
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
            self._settled.append(estimate_share(self._labels, start, end, cfg, self.share_model))
            self._emitted_end_s = end
        # Labels no later interval can hold.
        oldest_s = self._emitted_end_s + cfg.hop_s - cfg.interval_s
        if math.isfinite(oldest_s):
            self._labels = [lab for lab in self._labels if lab.impact_stamp_s >= oldest_s - 1e-9]
