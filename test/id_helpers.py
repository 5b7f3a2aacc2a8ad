"""Shared helpers of the identification tests: one simulated impact as a short stream."""

from __future__ import annotations

import copy
from typing import Any

from tail_beam_sim.physics.fidelity import FidelitySettings
from tail_beam_sim.physics.scene import Scene
from tail_beam_sim.physics.simulate import SimulationResult, simulate
from tail_beam_sim.physics.stream import StreamSimulator

# Long enough before contact for the detector's noise estimate (0.1 s blocks), after it for
# the camera timeout.
PRE_CONTACT_S = 0.25
WINDOW_S = 0.08


def impact(
    params: dict[str, Any],
    tier: str = "modal",
    noise: float = 1.0,
    sensors: dict[str, Any] | None = None,
    **fields: Any,
) -> SimulationResult:
    """Simulate one impact (impact fields as in impact_cmd) with its own baseline."""
    varied = copy.deepcopy(params)
    varied["sensors"].update(sensors or {})
    scene = Scene.from_params(
        varied, {"pre_contact_s": PRE_CONTACT_S, "window_s": WINDOW_S, **fields}
    )
    if noise != 1.0:
        from dataclasses import replace

        scene = replace(scene, sensors=scene.sensors.scaled_noise(noise))
    # The parameters' own bending modes: simulate() takes config/'s unless told (a foreign
    # support's modes were dropped here, and the tests of other supports ran on the shipped ones).
    return simulate(scene, tier=tier, settings=FidelitySettings.from_params(varied))


def stream_chunk(params, commands, until_s, **stream_options):
    """A continuous stream of impacts at given contact stamps (the beam carries its motion),
    as the simulator's Chunk: pressure, imu, vibration blocks, rebounds and truths."""
    varied = copy.deepcopy(params)
    varied["stream"] = {
        "tier": "modal",
        "min_impact_gap_s": 0.0,
        "command_lead_s": 0.001,
        "max_queued_impacts": 20,
        **stream_options,
    }
    simulator = StreamSimulator.from_params(varied)
    for stamp, command in commands:
        simulator.submit(command, contact_stamp_s=stamp)
    return simulator.advance(until_s)


def stream(params, commands, until_s, **stream_options):
    """A continuous stream of impacts at given contact stamps: pressure, imu, rebounds, truths."""
    chunk = stream_chunk(params, commands, until_s, **stream_options)
    return chunk.pressure, chunk.imu, [r for _, r in chunk.rebounds], [t for _, t in chunk.truths]


def replay_chunk(identifier, chunk):
    """Every label ``identifier`` gives for a simulated chunk's streams (pressure, IMU,
    rebounds and the accelerometer's blocks), as tail-beam identify replays a bag."""
    from tail_beam_id.stream.replay import replay

    return replay(
        identifier,
        chunk.pressure,
        chunk.imu,
        [r for _, r in chunk.rebounds],
        vibration=chunk.vibration,
    )
