"""Run identification methods over simulated scene sets and record, per impact, the truth and
what each method said (shared by training and evaluation)."""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from tail_beam_id.stream.identifier import StreamIdentifier
from tail_beam_id.stream.label import Label, match, match_tolerance_s
from tail_beam_id.stream.replay import point_tuples, replay
from tail_beam_id.study.dataset import (
    FOREIGN_RANGES,
    FOREIGN_SCENES,
    Setting,
    SupportStream,
    simulate_set,
    support_streams,
)
from tail_beam_sim.physics.scene import Scene


def true_profile_section(params: Mapping[str, Any]) -> dict[str, float]:
    """The profile section of the support in ``params`` known from its design: its true sway
    frequency, which marks the parameters as that support's. It holds nothing a calibration
    reads from a recording besides (the ringing's decay the detectors follow, the contact's
    hysteresis, the delays), so it is no upper bound (docs/results/structures.md)."""
    return {"rigid_mode_frequency_hz": Scene.from_params(params).support.rigid_mode_frequency_hz}


@dataclass
class Record:
    """One impact at one setting under one method: the truth and the matched label (or None).

    ``extra_labels`` counts labels that matched no impact (false detections; the rule:
    :func:`tail_beam_id.stream.label.match`); times in s.
    """

    scene_set: str
    setting: str
    method: str
    window_s: float
    index: int
    material: str
    is_coal: bool
    radius_m: float
    contact_stamp_s: float
    duration_s: float
    label: Label | None
    extra_labels: int
    wall_s: float
    calibrated: bool = False  # identified with the support's own profile instead of config/
    support: int | None = None  # a foreign set's support number (None: single impacts)
    # The struck support's contact law and the factor on its hysteresis
    # (support.contact_damping_scale):
    # what training's hysteresis network learns to read from a recording
    # (tail_beam_id.methods.hysteresis).
    contact_model: str | None = None
    contact_damping_scale: float | None = None
    # The recording's camera frame rate, Hz (None: not kept): training keeps a camera that
    # stamps the separation itself out of the models for config/ alone, which take every delay
    # as a reference camera's.
    camera_frame_rate_hz: float | None = None

    @property
    def correct(self) -> bool:
        return self.label is not None and (self.label.material == "coal") == self.is_coal


REPLAY_CHUNK_S = 0.01  # the stamp-time span of each delivery, as id_node's subscriptions give it
WHOLE_STREAM_CHUNK_S = 1e6  # s: one delivery holds an impact's whole streams


def run_set(
    params: Mapping[str, Any],
    scene_set: str,
    count: int,
    seed: int,
    chosen: Sequence[Setting],
    methods: Sequence[str],
    tier: str | None = None,
    windows_s: Sequence[float] = (),
    true_profile: bool = False,
    without_vibration_too: bool = False,
    chunk_s: float = REPLAY_CHUNK_S,
) -> Iterator[Record]:
    """Simulate ``count`` impacts of ``scene_set`` and identify each with every method, at the
    configured data window and at each of ``windows_s`` (s) as well; the accelerometer's blocks
    are fed wherever the setting (or drawn support) has one, as id_node feeds them. With
    ``true_profile`` an impact on a drawn support is identified knowing that support (a perfect
    calibration: what the calibrated models are trained on). With ``without_vibration_too`` an
    impact whose result has the accelerometer is also identified without it (setting
    ``<key>/no-vibration``:
    the same impact at a site with the IMU alone; training uses it). ``chunk_s``: the span of
    each delivery of the replay, s (the identifier's labels do not depend on it: the
    training replays each impact's streams in one delivery, WHOLE_STREAM_CHUNK_S)."""
    tolerance_s = match_tolerance_s(params["identification"])
    built: dict[Any, Any] = {}
    sections = [dict(params["identification"])] + [
        with_window(params["identification"], w) for w in windows_s
    ]
    nominal_scale = float(params["support"].get("contact_damping_scale", 1.0))
    cameras: dict[float, Mapping[str, Any]] = {}
    for impact in simulate_set(params, scene_set, count, seed, chosen, tier):
        law, scale = (
            (
                impact.support.contact_model,
                float(impact.support.values.get("contact_damping_scale", 1.0)),
            )
            if impact.support is not None
            else (impact.contact_model, nominal_scale)
        )
        support_params = params
        if true_profile and impact.support is not None:
            support_params = impact.support.apply(params)
            support_params["calibration"] = true_profile_section(support_params)
        for key, result, vibration in _feeds(impact.results, without_vibration_too):
            truth = result.truth()
            model_params = (
                with_camera(params, result.scene.sensors.camera_frame_rate_hz, cameras)
                if impact.support is None
                else support_params
            )
            for method in methods:
                for section in sections:
                    # The physics method is built for its support (the nominal one's kept per
                    # camera); the others read no support and are built once.
                    reuse_key: Any = method
                    if method == "physics":
                        nominal = impact.support is None or not true_profile
                        reuse_key = (method, id(model_params)) if nominal else None
                    reuse = built.get(reuse_key) if reuse_key is not None else None
                    identifier = StreamIdentifier(method, section, model_params, prebuilt=reuse)
                    if reuse_key is not None:
                        built[reuse_key] = identifier.method
                    started = time.perf_counter()
                    labels = replay(
                        identifier,
                        result.pressure,
                        result.imu,
                        [result.rebound],
                        vibration=vibration,
                        points=point_tuples([result.point] if result.point is not None else []),
                        chunk_s=chunk_s,
                    )
                    wall = time.perf_counter() - started
                    matching = match([truth], labels, tolerance_s)
                    paired = matching.label_index(0)
                    yield Record(
                        scene_set=scene_set,
                        setting=key,
                        method=method,
                        window_s=float(section["window_s"]),
                        index=impact.index,
                        material=truth["material"],
                        is_coal=truth["label"] == "coal",
                        radius_m=truth["radius_m"],
                        contact_stamp_s=result.contact_stamp_s,
                        duration_s=truth["final_separation_stamp"] - truth["contact_start_stamp"],
                        label=None if paired is None else labels[paired],
                        extra_labels=len(matching.extra),
                        wall_s=wall,
                        calibrated=identifier.calibrated,
                        contact_model=law,
                        contact_damping_scale=scale,
                        camera_frame_rate_hz=float(result.scene.sensors.camera_frame_rate_hz),
                    )


def with_camera(
    params: Mapping[str, Any], rate_hz: float, cache: dict[float, Mapping[str, Any]]
) -> Mapping[str, Any]:
    """``params`` with the camera of the recording (``sensors.camera_frame_rate_hz``, Hz), as
    its user would configure it: ``params`` itself when it is the configured one, else a copy
    (one per rate, kept in ``cache``) whose other sections are shared."""
    if float(params["sensors"]["camera_frame_rate_hz"]) == float(rate_hz):
        return params
    if rate_hz not in cache:
        cache[rate_hz] = {
            **params,
            "sensors": {**params["sensors"], "camera_frame_rate_hz": float(rate_hz)},
        }
    return cache[rate_hz]


def _feeds(
    results: Mapping[str, Any], without_vibration_too: bool
) -> Iterator[tuple[str, Any, Any]]:
    """(setting key, result, the vibration blocks to feed or None) of each result, and of each
    result with the accelerometer once more without it when asked."""
    for key, result in results.items():
        yield key, result, result.vibration
        if without_vibration_too and result.vibration.count:
            yield f"{key}/no-vibration", result, None


def with_window(section: Mapping[str, Any], window_s: float) -> dict[str, Any]:
    """The identification section with another data window (s); the windows that must fit in
    it shrink with it."""
    changed = dict(section)
    changed["window_s"] = window_s
    changed["vibration_window_s"] = (
        window_s  # every impact at this window, the accelerometer's too
    )
    changed["impulse_post_s"] = min(float(section["impulse_post_s"]), window_s)
    changed["overlap_window_s"] = min(float(section["overlap_window_s"]), window_s)
    return changed


FOREIGN_PROFILES = ("nominal", "self-calibrated", "true")  # how the identifier knows the support
DRAWN_SENSORS = (
    "drawn"  # the foreign set's setting whose sensors (rates, noise) are drawn with each support
)


def run_foreign(
    params: Mapping[str, Any],
    supports: int,
    impacts_per_support: int,
    seed: int,
    methods: Sequence[str],
    tier: str | None = None,
    profiles: Sequence[str] = FOREIGN_PROFILES[:2],
    chosen: Sequence[Setting | None] = (None,),
    scene_set: str = "foreign",
) -> Iterator[Record]:
    """The ``foreign`` scene set: drawn supports each recorded as one stream, identified with
    the nominal config/, after self-calibration on the stream itself (no labels), and (for
    reference) knowing the true support. Each support is recorded with each of ``chosen``
    sensor settings (the same supports and impacts at each: the comparison with the nominal
    support at the same rates), None meaning the sensors drawn with the support. The record's
    setting is ``<setting key or drawn>/<profile>``. Labels that match no impact count as extra
    on the stream's first record. ``scene_set`` (dataset.FOREIGN_SCENES) says which scene's
    impacts strike the supports: foreign the stream's, foreign_paper the paper's."""
    for setting in chosen:
        streams = support_streams(
            params,
            supports,
            impacts_per_support,
            seed,
            which=FOREIGN_RANGES[scene_set],
            tier=tier,
            setting=setting,
            scene=FOREIGN_SCENES[scene_set],
        )
        for number, recorded in enumerate(streams):
            yield from foreign_records(
                params,
                recorded,
                number,
                impacts_per_support,
                methods,
                profiles,
                setting.key if setting is not None else DRAWN_SENSORS,
                scene_set,
            )


def foreign_records(
    params: Mapping[str, Any],
    recorded: SupportStream,
    number: int,
    impacts_per_support: int,
    methods: Sequence[str],
    profiles: Sequence[str],
    sensors: str,
    scene_set: str = "foreign",
) -> Iterator[Record]:
    """The records of one recorded support stream (``number``: their ``support``), under each
    profile and method."""
    from tail_beam_id.calibration.offline import calibrate, with_profile

    section = dict(params["identification"])
    tolerance_s = match_tolerance_s(section)

    def identify(model_params: Mapping[str, Any], method: str) -> tuple[list[Label], float]:
        # The profile's detection settings (the ringing it measured) with the evaluation's section.
        detection = {
            **section.get("detection", {}),
            **(model_params.get("identification", {}).get("detection") or {}),
        }
        identifier = StreamIdentifier(method, {**section, "detection": detection}, model_params)
        started = time.perf_counter()
        labels = replay(
            identifier,
            recorded.pressure,
            recorded.imu,
            recorded.rebounds,
            vibration=recorded.vibration,
            points=point_tuples(recorded.points),
        )
        return labels, time.perf_counter() - started

    for profile in profiles:
        model_params: Mapping[str, Any] = params
        if profile == "true":
            model_params = {
                **recorded.params,
                "calibration": true_profile_section(recorded.params),
            }
        elif profile == "self-calibrated":
            v = recorded.vibration
            found = calibrate(
                params,
                (recorded.pressure.stamp_s, recorded.pressure.pressure_pa),
                (recorded.imu.stamp_s, recorded.imu.linear_acceleration_mps2[:, 2]),
                lambda calibrated: identify(calibrated, "statistical")[0],
                (v.sample_stamps_s(), v.accel_mps2) if v is not None and v.count else None,
                [r.stamp_s for r in recorded.rebounds],
            )
            model_params = with_profile(params, found)
        for method in methods:
            labels, wall = identify(model_params, method)
            matching = match(recorded.truths, labels, tolerance_s)
            for k, truth in enumerate(recorded.truths):
                paired = matching.label_index(k)
                yield Record(
                    scene_set=scene_set,
                    setting=f"{sensors}/{profile}",
                    method=method,
                    window_s=float(section["window_s"]),
                    index=number * impacts_per_support + k,
                    material=truth["material"],
                    is_coal=truth["label"] == "coal",
                    radius_m=truth["radius_m"],
                    contact_stamp_s=truth["contact_start_stamp"],
                    duration_s=truth["final_separation_stamp"] - truth["contact_start_stamp"],
                    label=None if paired is None else labels[paired],
                    extra_labels=len(matching.extra) if k == 0 else 0,
                    wall_s=wall / max(len(recorded.truths), 1),
                    calibrated=profile != "nominal",
                    support=number,
                )
