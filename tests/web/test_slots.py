from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from tourbot.web.slots import Role, SlotArbiter, SlotConfig


def test_first_booking_holds_and_others_queue_in_order() -> None:
    arb: SlotArbiter[str] = SlotArbiter()
    arb.book("a", 0.0)
    arb.book("b", 1.0)
    arb.book("c", 2.0)
    assert arb.holder == "a"
    assert arb.view("b", 2.0).position == 1
    assert arb.view("c", 2.0).position == 2
    assert arb.view("c", 2.0).role is Role.QUEUED
    assert arb.view("zz", 2.0).role is Role.WATCHER
    assert arb.may_command("a", 3.0)
    assert not arb.may_command("b", 3.0)
    assert not arb.may_command("zz", 3.0)


def test_slot_expires_after_ten_minutes_and_passes_on() -> None:
    arb: SlotArbiter[str] = SlotArbiter(SlotConfig(answer_timeout=1e9))
    arb.book("a", 0.0)
    arb.book("b", 1.0)
    assert [e.client for e in arb.take_events()] == ["a"]
    assert arb.view("a", 100.0).time_left == 500.0
    assert arb.view("b", 100.0).time_left == 500.0
    arb.update(600.0)
    events = arb.take_events()
    assert [(e.kind, e.client, e.reason) for e in events] == [
        ("ended", "a", "expired"),
        ("started", "b", "next in queue"),
    ]
    assert arb.holder == "b"
    assert arb.time_left(600.0) == 600.0
    assert not arb.may_command("a", 601.0)


def test_holder_leaving_hands_over_at_once() -> None:
    arb: SlotArbiter[str] = SlotArbiter()
    arb.book("a", 0.0)
    arb.book("b", 0.0)
    arb.leave("a", 5.0)
    assert arb.holder == "b"
    assert arb.time_left(5.0) == 600.0


def test_silent_holder_and_silent_queued_clients_are_dropped() -> None:
    arb: SlotArbiter[str] = SlotArbiter(SlotConfig(answer_timeout=20.0))
    arb.book("a", 0.0)
    arb.book("b", 0.0)
    arb.book("c", 0.0)
    for t in (10.0, 20.0, 30.0):
        arb.seen("b", t)
    arb.update(25.0)
    events = arb.take_events()
    assert ("ended", "a", "silent") in [(e.kind, e.client, e.reason) for e in events]
    assert arb.holder == "b"
    assert "c" not in arb.queue
    arb.seen("b", 40.0)
    assert arb.may_command("b", 45.0)


def test_onboard_and_staff_take_precedence() -> None:
    arb: SlotArbiter[str] = SlotArbiter(SlotConfig(onboard_hold=60.0))
    arb.book("a", 0.0)
    arb.onboard_touch(10.0)
    assert not arb.may_command("a", 11.0)
    assert arb.view("a", 11.0).onboard
    arb.seen("a", 70.0)
    assert arb.may_command("a", 71.0)
    arb.staff_stop()
    assert not arb.may_command("a", 72.0)
    assert arb.view("a", 72.0).staff_stop
    arb.staff_release()
    assert arb.may_command("a", 73.0)


def test_booking_twice_keeps_one_place() -> None:
    arb: SlotArbiter[str] = SlotArbiter()
    arb.book("a", 0.0)
    arb.book("b", 0.0)
    arb.book("b", 1.0)
    arb.book("a", 1.0)
    assert arb.queue == ["b"]


@settings(max_examples=100, deadline=None)
@given(
    st.lists(
        st.tuples(st.sampled_from(["book", "leave", "seen", "tick"]), st.integers(0, 5), st.floats(0, 50)),
        max_size=60,
    )
)
def test_invariants_under_any_sequence(ops: list[tuple[str, int, float]]) -> None:
    """At most one holder, never queued twice, the holder is not queued, slots never exceed 10 min."""
    arb: SlotArbiter[int] = SlotArbiter(SlotConfig(slot_length=100.0, answer_timeout=30.0))
    now = 0.0
    for op, client, dt in ops:
        now += dt
        if op == "book":
            arb.book(client, now)
        elif op == "leave":
            arb.leave(client, now)
        elif op == "seen":
            arb.seen(client, now)
        else:
            arb.update(now)
        assert len(set(arb.queue)) == len(arb.queue)
        assert arb.holder not in arb.queue
        assert 0.0 <= arb.time_left(now) <= 100.0
        holders = [c for c in range(6) if arb.may_command(c, now)]
        assert len(holders) <= 1
        if arb.queue:
            assert arb.holder is not None


def test_one_group_holds_at_most_its_places() -> None:
    """Clients of one address (group) hold at most ``places_per_group`` places, the slot included;
    a place freed is bookable again, and other groups are not held back."""
    arb: SlotArbiter[str] = SlotArbiter(SlotConfig(places_per_group=2))
    assert arb.book("a1", 0.0, group="10.0.0.1")
    assert arb.book("a2", 0.0, group="10.0.0.1")
    assert not arb.book("a3", 0.0, group="10.0.0.1")
    assert arb.book("a1", 1.0, group="10.0.0.1")  # booking again: still its one place
    assert arb.book("b1", 1.0, group="10.0.0.2")
    assert (arb.holder, arb.queue) == ("a1", ["a2", "b1"])
    arb.leave("a2", 2.0)
    assert arb.book("a3", 2.0, group="10.0.0.1")
    assert arb.queue == ["b1", "a3"]
