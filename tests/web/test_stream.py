from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.web.stream import (
    MAX_BODIES,
    Body,
    Scene,
    StreamBroadcast,
    StreamConfig,
    StreamDecoder,
    StreamEncoder,
    StreamError,
    StreamFidelity,
    websocket_frame,
)

coord = st.floats(-300.0, 300.0, allow_nan=False)
speed = st.floats(-2.4, 2.4, allow_nan=False)
angle = st.floats(-math.pi, math.pi, allow_nan=False)


def _angle_diff(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


@settings(max_examples=60, deadline=None)
@given(
    robot=st.tuples(coord, coord, speed, speed, angle),
    people=st.dictionaries(st.integers(1, 65535), st.tuples(coord, coord, speed, speed), max_size=20),
)
def test_keyframe_is_within_half_a_quantum(
    robot: tuple[float, float, float, float, float], people: dict[int, tuple[float, float, float, float]]
) -> None:
    config = StreamConfig()
    scene = Scene(
        1000.0,
        Body(0, robot[0], robot[1], robot[2], robot[3], robot[4]),
        tuple(Body(i, *p) for i, p in people.items()),
    )
    message = StreamEncoder(config).encode(scene)
    assert message is not None
    assert len(message) == 1 + 8 + 3 + (11 + 2) + (8 + 2) * len(people) + 1  # each body with its age
    decoder = StreamDecoder(config)
    decoder.feed(message)
    got = decoder.scene()
    half = config.position_quantum / 2 + 1e-9
    assert abs(got.robot.x - robot[0]) <= half
    assert abs(got.robot.y - robot[1]) <= half
    assert abs(got.robot.vx - robot[2]) <= config.velocity_quantum / 2 + 1e-9
    assert _angle_diff(got.robot.theta, robot[4]) <= math.pi / 65536 + 1e-9
    assert {p.id for p in got.people} == set(people)
    for p in got.people:
        assert abs(p.x - people[p.id][0]) <= half
        assert abs(p.y - people[p.id][1]) <= half
        vx, vy = people[p.id][2:]
        if math.hypot(vx, vy) < config.moving_speed:  # a person this slow is sent standing
            vx = vy = 0.0
        assert abs(p.vx - vx) <= config.velocity_quantum / 2 + 1e-9
        assert abs(p.vy - vy) <= config.velocity_quantum / 2 + 1e-9


def _walk(t: float, i: int) -> Body:
    """A person on a circle: velocity changes all the time, so dead reckoning must be corrected."""
    r, w = 2.0 + i, 0.4 / (1 + i)
    return Body(
        i, r * math.cos(w * t), r * math.sin(w * t), -r * w * math.sin(w * t), r * w * math.cos(w * t)
    )


@settings(max_examples=30, deadline=None)
@given(skips=st.lists(st.booleans(), min_size=10, max_size=80), leave_at=st.integers(0, 80))
def test_deltas_keep_every_body_within_tolerance(skips: list[bool], leave_at: int) -> None:
    """Whatever states a slow client misses, what it shows stays within the tolerance."""
    config = StreamConfig()
    encoder, decoder = StreamEncoder(config), StreamDecoder(config)
    t0 = 5000.0
    for k, skip in enumerate(skips):
        t = t0 + k / config.rate_hz
        people = tuple(_walk(t, i) for i in range(1, 8) if not (i == 3 and k >= leave_at))
        robot = Body(0, 0.5 * (t - t0), 1.0, 0.5, 0.0, math.remainder(0.3 * (t - t0), 2 * math.pi), 0.3)
        scene = Scene(t, robot, people)
        if skip and k > 0:
            continue  # this client was too slow for this state: it never sees it
        message = encoder.encode(scene)
        if message is not None:
            decoder.feed(message)
        shown = decoder.scene(t)
        tol = config.position_tolerance + 2 * config.position_quantum
        person_tol = config.person_tolerance + 2 * config.position_quantum
        assert {p.id for p in shown.people} == {p.id for p in people}
        truth = {p.id: p for p in people}
        for p in shown.people:
            assert math.hypot(p.x - truth[p.id].x, p.y - truth[p.id].y) <= person_tol
        assert math.hypot(shown.robot.x - robot.x, shown.robot.y - robot.y) <= tol
        assert _angle_diff(shown.robot.theta, robot.theta) <= config.heading_tolerance + 0.01


@settings(max_examples=30, deadline=None)
@given(
    viewers=st.lists(
        st.tuples(st.integers(0, 60), st.lists(st.booleans(), min_size=80, max_size=80)),
        min_size=1,
        max_size=5,
    ),
    leave_at=st.integers(0, 80),
)
def test_broadcast_keeps_every_viewer_within_tolerance(
    viewers: list[tuple[int, list[bool]]], leave_at: int
) -> None:
    """Viewers join at any state and skip any states (slow ones): each holds the scene within the
    tolerance, and all the up-to-date ones get the very same bytes."""
    config = StreamConfig()
    broadcast = StreamBroadcast(config)
    decoders = [StreamDecoder(config) for _ in viewers]
    held = [0] * len(viewers)
    t0 = 5000.0
    for k in range(80):
        t = t0 + k / config.rate_hz
        people = tuple(_walk(t, i) for i in range(1, 8) if not (i == 3 and k >= leave_at))
        robot = Body(0, 0.5 * (t - t0), 1.0, 0.5, 0.0, math.remainder(0.3 * (t - t0), 2 * math.pi), 0.3)
        broadcast.push(Scene(t, robot, people))
        sent: dict[int, bytes] = {}
        for v, (joins, skips) in enumerate(viewers):
            if k < joins or (skips[k] and held[v]):
                continue  # not here yet, or too slow for this state
            message = broadcast.message_for(held[v])
            held[v] = broadcast.version
            if message is not None:
                if held[v] - 1 == k and message[0] == 2:
                    assert sent.setdefault(message[0], message) is message  # one encoding for all
                decoders[v].feed(message)
            shown = decoders[v].scene(t)
            tol = config.position_tolerance + 2 * config.position_quantum
            person_tol = config.person_tolerance + 2 * config.position_quantum
            truth = {p.id: p for p in people}
            assert {p.id for p in shown.people} == set(truth)
            for p in shown.people:
                assert math.hypot(p.x - truth[p.id].x, p.y - truth[p.id].y) <= person_tol
            assert math.hypot(shown.robot.x - robot.x, shown.robot.y - robot.y) <= tol
            assert _angle_diff(shown.robot.theta, robot.theta) <= config.heading_tolerance + 0.01


@pytest.mark.parametrize("size", [0, 1, 125, 126, 65535, 65536, 70000])
def test_websocket_frame_is_the_protocols_own_unmasked_binary_frame(size: int) -> None:
    from websockets.frames import Frame, Opcode

    payload = bytes(k % 251 for k in range(size))
    assert websocket_frame(payload) == Frame(Opcode.BINARY, payload).serialize(mask=False)


def test_broadcast_frames_each_state_once_for_every_viewer() -> None:
    """Up-to-date viewers share one delta frame, joining and late viewers one keyframe frame: the
    same objects, built once per state, each the frame of its message."""
    broadcast = StreamBroadcast(StreamConfig())
    assert broadcast.frame_for(0) is None  # nothing pushed yet
    for k in range(3):
        t = 100.0 + k
        broadcast.push(Scene(t, Body(0, 0.5 * k, 0.0), (_walk(t, 1),)))  # a robot never predicted
        behind = [broadcast.frame_for(0), broadcast.frame_for(0)]
        if k == 0:
            continue
        up_to_date = [broadcast.frame_for(broadcast.version - 1) for _ in range(2)]
        for first, second in (behind, up_to_date):
            assert first is not None
            assert second is not None
            assert first[1] is second[1]
            assert first[1] == websocket_frame(first[0])
        keyframe, delta = behind[0], up_to_date[0]
        assert keyframe is not None
        assert delta is not None
        assert keyframe[0][0] == 1  # a keyframe
        assert delta[0][0] == 2  # a delta
        assert broadcast.frame_for(broadcast.version) is None


def test_broadcast_keyframe_after_the_counter_wrap() -> None:
    """A viewer joining after the 16-bit time counter wrapped decodes the right time."""
    config = StreamConfig(refresh_period=1.0)
    broadcast = StreamBroadcast(config)
    for k in range(800):
        broadcast.push(Scene(100.0 + k, Body(0, 0.01 * k, 0.0, 0.01, 0.0)))
    late = StreamDecoder(config)
    key = broadcast.message_for(0)
    assert key is not None
    assert key[0] == 1
    late.feed(key)
    assert late.t == pytest.approx(899.0, abs=0.006)
    assert late.scene().robot.x == pytest.approx(7.99, abs=0.01)
    broadcast.push(Scene(900.5, Body(0, 8.005, 0.0, 0.01, 0.0)))
    assert broadcast.message_for(broadcast.version) is None
    delta = broadcast.message_for(broadcast.version - 1)
    if delta is not None:
        late.feed(delta)
    assert late.scene(900.5).robot.x == pytest.approx(8.005, abs=0.02)


def test_still_scene_sends_nothing_until_refresh() -> None:
    config = StreamConfig(refresh_period=2.0)
    encoder = StreamEncoder(config)
    scene = Scene(10.0, Body(0, 1.0, 2.0), (Body(4, 3.0, 3.0),))
    assert encoder.encode(scene) is not None
    assert encoder.encode(Scene(10.2, scene.robot, scene.people)) is None
    refresh = encoder.encode(Scene(12.0, scene.robot, scene.people))
    assert refresh is not None
    assert refresh[0] == 2
    assert len(refresh) == 4 + 11 + 8 + 1


def test_constant_velocity_walkers_cost_only_refreshes() -> None:
    """7 people walking straight at 1 m/s: after the keyframe, only the periodic refresh."""
    config = StreamConfig()
    encoder = StreamEncoder(config)
    total = 0
    for k in range(5 * 60):
        t = k / config.rate_hz
        people = tuple(Body(i, 0.5 * t, i * 1.0, 0.5, 0.0) for i in range(1, 8))
        message = encoder.encode(Scene(t, Body(0, 0.0, 0.0), people))
        total += len(message or b"")
    bits_per_second = 8 * total / 60.0
    assert bits_per_second < 500


def test_reset_gives_a_keyframe_and_the_decoder_follows_it() -> None:
    encoder, decoder = StreamEncoder(), StreamDecoder()
    decoder.feed(encoder.encode(Scene(1.0, Body(0, 1.0, 1.0))) or b"")
    encoder.reset()
    key = encoder.encode(Scene(2.0, Body(0, 4.0, 1.0), (Body(9, 0.0, 0.0),)))
    assert key is not None
    assert key[0] == 1
    decoder.feed(key)
    assert decoder.scene().robot.x == pytest.approx(4.0)
    assert [p.id for p in decoder.scene().people] == [9]


def test_time_survives_the_counter_wrap() -> None:
    config = StreamConfig(refresh_period=1.0)
    encoder, decoder = StreamEncoder(config), StreamDecoder(config)
    for k in range(0, 800, 1):  # 800 s at 1 Hz: the 16-bit 10 ms counter wraps after 655 s
        message = encoder.encode(Scene(100.0 + k, Body(0, 0.0, 0.0)))
        if message is not None:
            decoder.feed(message)
    assert decoder.t == pytest.approx(100.0 + 799, abs=0.01)


@pytest.mark.parametrize("bad", [b"", b"\x02\x00\x00\x00", b"\x07\x00\x00\x00\x00", b"\x01\x00\x00"])
def test_malformed_messages_raise_and_change_nothing(bad: bytes) -> None:
    decoder = StreamDecoder()
    with pytest.raises(StreamError):
        decoder.feed(bad)
    assert decoder.epoch is None


def test_trailing_bytes_are_rejected() -> None:
    message = StreamEncoder().encode(Scene(1.0, Body(0, 1.0, 1.0)))
    assert message is not None
    with pytest.raises(StreamError, match="trailing"):
        StreamDecoder().feed(message + b"\x00")


def test_person_id_zero_is_refused() -> None:
    with pytest.raises(StreamError, match="person id"):
        StreamEncoder().encode(Scene(1.0, Body(0, 0.0, 0.0), (Body(0, 1.0, 1.0),)))


def test_starting_and_stopping_are_sent_at_once() -> None:
    encoder = StreamEncoder()
    assert encoder.encode(Scene(0.0, Body(0, 1.0, 1.0))) is not None
    assert encoder.encode(Scene(0.2, Body(0, 1.0, 1.0, 0.05, 0.0))) is None  # creeping: still "at rest"
    started = encoder.encode(Scene(0.4, Body(0, 1.0, 1.0, 0.3, 0.0)))
    assert started is not None
    decoder = StreamDecoder()
    decoder.feed(StreamEncoder().encode(Scene(0.4, Body(0, 1.0, 1.0, 0.3, 0.0))) or b"")
    assert decoder.scene().robot.vx == pytest.approx(0.3)
    assert encoder.encode(Scene(0.6, Body(0, 1.06, 1.0, 0.3, 0.0))) is None
    assert encoder.encode(Scene(0.8, Body(0, 1.1, 1.0, 0.0, 0.0))) is not None  # stopped


def test_a_crowd_denser_than_a_message_streams_the_people_nearest_the_robot() -> None:
    from tourbot.web.hub import scene_of
    from tourbot.web.link import PersonView, RobotView

    people = tuple(PersonView(i, 1.0 + 0.1 * i, 0.0) for i in range(400))  # id i is 0.1 i m away
    scene = scene_of(RobotView(0.0, 1.0, 0.0, 0.0, people=people), t=10.0)
    assert len(scene.people) == MAX_BODIES - 1
    assert max(p.x for p in scene.people) == pytest.approx(1.0 + 0.1 * (MAX_BODIES - 2))
    message = StreamEncoder().encode(scene)  # fits in one message
    decoder = StreamDecoder()
    decoder.feed(message or b"")
    assert len(decoder.scene().people) == MAX_BODIES - 1


def test_standing_visitors_with_jittering_velocities_cost_only_refreshes() -> None:
    """20 tracked visitors standing at an exhibit: their estimated velocities jitter by about
    5 cm/s and their positions by 2 cm; they are sent standing, so only the refresh costs."""
    rng = np.random.default_rng(3)
    config = StreamConfig()
    encoder, decoder = StreamEncoder(config), StreamDecoder(config)
    home = rng.uniform(-3, 3, (20, 2))
    total = 0
    for k in range(5 * 60):
        t = k / config.rate_hz
        xy = home + rng.normal(0.0, 0.02, home.shape)
        v = rng.normal(0.0, 0.05, home.shape)
        people = tuple(Body(i + 1, *xy[i], *v[i]) for i in range(len(home)))
        message = encoder.encode(Scene(t, Body(0, 0.0, 0.0), people))
        if message:
            decoder.feed(message)
            total += len(message)
        shown = {p.id: (p.x, p.y) for p in decoder.scene(t).people}
        assert max(math.hypot(*(np.array(shown[i + 1]) - home[i])) for i in range(len(home))) < 0.2
    assert 8 * total / 60.0 < 400  # bits per second; velocities extrapolated: about 3 kbit/s


def test_the_budget_costs_nothing_while_the_tolerances_fit_in_it() -> None:
    """Seven walkers and a turning robot (the paper's scene) need less than the budget: the
    messages are the very ones an unlimited budget gives."""
    limited, unlimited = StreamEncoder(StreamConfig()), StreamEncoder(StreamConfig(bitrate=1e9))
    total = 0
    for k in range(5 * 60):
        t = 100.0 + k / 5.0
        robot = Body(0, 0.5 * k / 5.0, 1.0, 0.5, 0.0, math.remainder(0.3 * k / 5.0, 2 * math.pi), 0.3)
        scene = Scene(t, robot, tuple(_walk(t, i) for i in range(1, 8)))
        message = limited.encode(scene)
        assert message == unlimited.encode(scene)
        total += len(message or b"")
    assert 0 < 8 * total / 60.0 < StreamConfig().bitrate


def _jittering_crowd(
    n: int, seconds: float, config: StreamConfig, seed: int = 5
) -> tuple[int, StreamEncoder]:
    """``n`` tracked walkers whose estimates jitter (2 cm, 10 cm/s), around a robot driving at
    0.3 m/s: the bytes of the deltas after the keyframe, and the encoder."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-6, 6, (n, 2))
    heading = rng.uniform(-math.pi, math.pi, n)
    velocity = 0.8 * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    encoder, decoder = StreamEncoder(config), StreamDecoder(config)
    total = 0
    for k in range(int(seconds * config.rate_hz)):
        t = k / config.rate_hz
        turn = np.sin(0.3 * t + heading)[:, None] * 0.3  # walkers curve a little
        xy = start + velocity * t + turn + rng.normal(0.0, 0.02, start.shape)
        v = velocity + rng.normal(0.0, 0.1, start.shape)
        people = tuple(Body(i + 1, *xy[i], *v[i]) for i in range(n))
        robot = Body(0, 0.3 * t, 0.0, 0.3, 0.0)
        message = encoder.encode(Scene(t, robot, people))
        if message is not None:
            decoder.feed(message)
            total += len(message) + config.framing_bytes if k else 0
        shown = decoder.scene(t)
        robot_error = math.hypot(shown.robot.x - robot.x, shown.robot.y - robot.y)
        assert robot_error <= config.position_tolerance + 0.02
    return total, encoder


def test_a_dense_crowd_keeps_to_the_budget_and_the_robot_to_its_tolerance() -> None:
    config = StreamConfig()
    total, encoder = _jittering_crowd(40, 60.0, config)
    assert 8 * total / 60.0 <= config.bitrate * 1.02  # the bucket's one second of burst, spread
    unlimited, _ = _jittering_crowd(40, 60.0, StreamConfig(bitrate=1e9))
    assert unlimited > 2 * total  # the tolerances alone would need far more
    fidelity = encoder.fidelity.summary()
    assert fidelity["samples"] > 0.9 * 40 * 300  # nearly every person shown nearly all the time
    assert fidelity["mean_m"] < 0.3  # and within 30 cm of its estimate on average (7 cm unlimited)


def test_the_worst_predicted_person_is_sent_first() -> None:
    config = StreamConfig(min_batch=1)
    encoder = StreamEncoder(config)
    people = (Body(1, 0.0, 0.0), Body(2, 5.0, 0.0))
    encoder.encode(Scene(0.0, Body(0, 0.0, 0.0), people))
    # after 0.15 s the bucket holds 15 bytes: room for one person beside the message's head
    message = encoder.encode(Scene(0.15, Body(0, 0.0, 0.0), (Body(1, 0.3, 0.0), Body(2, 5.9, 0.0))))
    assert message is not None
    decoder = StreamDecoder(config)
    decoder.feed(StreamEncoder(config).encode(Scene(0.0, Body(0, 0.0, 0.0), people)) or b"")
    decoder.feed(message)
    shown = {p.id: p.x for p in decoder.scene().people}
    assert shown == {1: 0.0, 2: pytest.approx(5.9)}  # 90 cm off goes before 30 cm off


def test_fidelity_quantiles() -> None:
    fidelity = StreamFidelity()
    for e in (0.004, 0.05, 0.05, 0.3, 5.0):
        fidelity.add(e)
    assert fidelity.quantile(0.5) == pytest.approx(0.06)
    assert fidelity.quantile(1.0) == 2.0
    assert fidelity.worst == 5.0
    assert fidelity.mean == pytest.approx(5.404 / 5)


def test_the_objects_message_is_sent_on_change_only() -> None:
    import json

    from tourbot.web.link import ObjectView
    from tourbot.web.stream import ObjectsPayload

    def door(dy: float) -> ObjectView:
        return ObjectView("d", "door", ((7.0, 6.0), (7.9, 6.0 + dy), (7.9, 6.04 + dy)))

    payload = ObjectsPayload(tolerance=0.03)
    first = payload.update([door(0.0)])
    assert first is not None
    assert payload.message == first
    message = json.loads(first)
    assert message["type"] == "objects"
    assert message["objects"][0]["outline"][1] == [7.9, 6.0]
    assert message["objects"][0]["kind"] == "door"
    assert payload.update([door(0.02)]) is None  # within the tolerance: the viewers keep theirs
    assert payload.message == first
    moved = payload.update([door(0.5)])
    assert moved is not None
    assert json.loads(moved)["objects"][0]["outline"][1] == [7.9, 6.5]
    assert payload.update([door(0.5)]) is None
    assert payload.update([]) is not None  # gone
    assert len(payload.update([door(0.0)]) or "") < 200  # a door costs a hundred bytes, once


def test_a_body_is_dead_reckoned_up_to_the_horizon_and_a_late_joiner_holds_the_same() -> None:
    """The page (static/stream.js) stops extrapolating a body ``horizon`` seconds after its last
    message; the server's model of a viewer does the same, and a viewer that joins later gets each
    body with its age, so that it stops it at the same place and time."""
    config = StreamConfig(horizon=3.0, refresh_period=100.0)
    broadcast = StreamBroadcast(config)
    walker = Body(1, 0.0, 0.0, 1.0, 0.0)
    broadcast.push(Scene(100.0, Body(0, 0.0, 0.0), (walker,)))
    first = StreamDecoder(config)
    first.feed(broadcast.message_for(0) or b"")
    broadcast.push(Scene(101.6, Body(0, 0.0, 0.0), (Body(1, 1.6, 0.0, 1.0, 0.0),)))  # as predicted
    assert broadcast.message_for(1) is None
    late = StreamDecoder(config)
    late.feed(broadcast.message_for(0) or b"")  # a keyframe: the walker sent 1.6 s before
    for t in (101.6, 102.5, 103.0, 110.0):
        expected = min(t - 100.0, 3.0)
        assert first.scene(t).people[0].x == pytest.approx(expected)
        assert late.scene(t).people[0].x == pytest.approx(expected)
