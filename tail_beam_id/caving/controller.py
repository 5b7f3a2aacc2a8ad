"""The parameters of the caving windows' controller (``caving_node``, section ``caving_node``
of config/caving_node.yaml): which rule closes, which supports it serves, when the windows open.
Declared here, below the ROS floor, so that the identifier's parameter reference
(tail_beam_id.ros.id_node) lists them with its own."""

from __future__ import annotations

from tail_beam_sim import topics
from tail_beam_sim.spec import Section, choice, number, of_kind, positive, text

CLOCK_TOPICS = (topics.JACK_PRESSURE, topics.IMU, topics.VIBRATION)  # header first, stamp first

CAVING_NODE = Section(
    "caving_node",
    "The caving windows' controller caving_node (docs/caving.md).",
    (
        text(
            "rule",
            "Closing rule: fixed_time, first_gangue, share_<level> (one per caving.share_levels), "
            "sprt, share_estimate or oracle.",
        ),
        of_kind(
            "strs",
            "supports",
            'Namespaces of the supports served, in drawing order ("" = the node\'s own).',
        ),
        choice(
            "clock_topic",
            "Sensor topic whose newest header stamp is a support's clock.",
            CLOCK_TOPICS,
        ),
        number(
            "open_at_s", "Stamp time of its support at which the first window opens.", "s", 0.0
        ),
        number(
            "next_open_delay_s",
            "From a window's closing to the next support's window opening, on that support's "
            "clock.",
            "s",
            0.0,
            3600.0,
        ),
        positive(
            "max_open_s", "A window its rule has not closed by then is closed.", "s", high=1e5
        ),
        positive("tick_period_s", "Wall-clock period of the controller's tick.", "s", high=10.0),
        number(
            "settle_s",
            "Wall time a window_cmd subscriber must have been matched before the first command "
            "(discovery is asymmetric).",
            "s",
            0.0,
            60.0,
        ),
    ),
    file="caving_node.yaml",
)
