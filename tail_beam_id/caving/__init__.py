"""Caving decisions from labels: the events a window's controller hears (labels, gangue-share
estimates, the truth) and the closing rules that turn them into a decision to close
(docs/caving.md). Pure: no ROS, no clock of its own."""

__all__ = ["events", "rules"]
