"""Identification over live or recorded streams: buffers of samples, impacts found and paired
with their rebounds, each decided once and labelled (the same code serves id_node and
``tail-beam identify``)."""

__all__ = [
    "acceleration",
    "association",
    "buffers",
    "camera_frame",
    "channels",
    "config",
    "decision",
    "detection",
    "identifier",
    "label",
    "readiness",
    "release",
    "replay",
    "retention",
]
