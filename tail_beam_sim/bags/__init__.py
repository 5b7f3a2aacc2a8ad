"""rosbag2 bags: records to write, reading with explicit errors, segmented writing and repair (no
ROS)."""

__all__ = ["records", "read", "write"]
