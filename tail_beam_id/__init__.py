"""Coal-gangue identification over the sensor streams (imports tail_beam_sim, never the reverse).

Floors, lowest first; a module imports its own floor and those below only:
``signals`` (what a recording says about each impact), ``methods`` (P(coal) from features),
``stream`` (impacts found, paired and labelled over a stream), ``calibration`` (fitting to one
support), ``caving`` (closing a caving window on labels), ``ros`` (id_node), ``study``
(evaluation, training, charts), ``cli`` (the verbs).
"""

__all__ = ["calibration", "caving", "cli", "methods", "ros", "signals", "stream", "study"]
