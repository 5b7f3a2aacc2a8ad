"""The identifier's ROS 2 room: id_node, its entry point and the arrival gate that orders the
streams as they come over the middleware."""

__all__ = ["arrival", "id_node", "start"]
