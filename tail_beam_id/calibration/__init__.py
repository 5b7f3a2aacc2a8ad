"""Fitting identification to one support from its own recording: offline over a bag, online in
id_node, and the bending modes read from the ring-down."""

__all__ = ["modes", "offline", "online"]
