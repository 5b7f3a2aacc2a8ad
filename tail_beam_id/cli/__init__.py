"""``tail-beam`` subcommands of the identification package."""

__all__ = ["identify_cmd", "evaluate_cmd", "demo_cmd", "calibrate_cmd"]
