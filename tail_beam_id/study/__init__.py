"""Studies over simulated supports: drawn supports and scene sets, runs through the identifier,
evaluation with intervals, training of the shipped models, and charts."""

__all__ = ["charts", "dataset", "evaluation", "runs", "supports", "training"]
