"""Thin ROS 2 adapters over the core: messages, parameters, spinning, and the three simulator-side
nodes.

The only package of tail_beam_sim that imports rclpy."""

__all__ = [
    "messages",
    "params",
    "spin",
    "sim_node",
    "recorder_node",
    "replay_node",
    "usage",
    "client",
]
