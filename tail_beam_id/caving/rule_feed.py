"""A window controller's queue of what it has learnt and not yet told its closing rule: the
study's feeds (stand-in and identified sources) release events to the rule in the order they
become known, cell by cell."""

from __future__ import annotations

import heapq
import itertools

from tail_beam_id.caving.events import Event, Opened, Tick, TrueShare
from tail_beam_id.caving.rules import Rule


class RuleFeed:
    """What a window's controller has learnt and not yet told its rule: events in the order
    they become known (their ``known_s``, then the order pushed), released up to a stamp."""

    def __init__(self, rule: Rule, opened_s: float) -> None:
        self.rule = rule
        self.pending: list[tuple[float, int, Event]] = []
        self.order = itertools.count()
        self.decided = False
        rule.feed(Opened(opened_s))

    def _push(self, event: Event) -> None:
        heapq.heappush(self.pending, (event.known_s, next(self.order), event))

    def _end_cell(self, end_s: float, share: float) -> bool:
        """The cell's true share and the clock's tick at ``end_s``, then every event known by
        then fed to the rule; whether it has decided."""
        self._push(TrueShare(end_s, share))
        self._push(Tick(end_s))
        while self.pending and self.pending[0][0] <= end_s:
            event = heapq.heappop(self.pending)[2]
            if self.rule.feed(event) is not None:
                self.decided = True
        return self.decided
