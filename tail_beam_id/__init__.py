"""Coal-gangue identification over the sensor streams: detection, features, methods, the
stream identifier, its ROS node, evaluation and training (imports tail_beam_sim, never the reverse)."""

__all__ = ["detection", "features", "methods", "identifier", "id_node", "evaluation", "training", "dataset", "runs", "replay", "charts", "cli"]
