"""Bag replay timing with a fake clock: original spacing, rate factor, loops with a monotonic bag time."""
import pytest

from air_hockey_agent.bags.playback import paced


class FakeTime:
    def __init__(self):
        self.now = 100.0

    def clock(self):
        return self.now

    def wait(self, seconds):
        self.now += seconds


MESSAGES = [("/a", 1_000_000_000, b"1"), ("/b", 1_500_000_000, b"2"), ("/a", 3_000_000_000, b"3")]


def test_messages_keep_their_spacing_divided_by_the_rate():
    t = FakeTime()
    seen = [(t.now, topic) for topic, _, _ in paced(lambda: MESSAGES, 2.0, False, t.clock, t.wait)]
    assert [round(w - 100.0, 9) for w, _ in seen] == [0.0, 0.25, 1.0]


def test_loop_continues_bag_time_monotonically():
    t = FakeTime()
    gen = paced(lambda: MESSAGES, 1.0, True, t.clock, t.wait)
    times = [next(gen)[1] for _ in range(7)]
    assert all(b > a for a, b in zip(times, times[1:]))
    assert times[3] - times[0] == 2_000_000_000 + 2_000_000_000 // 3


def test_bad_rate_and_empty_bag():
    with pytest.raises(ValueError):
        list(paced(lambda: MESSAGES, 0.0, False))
    assert list(paced(lambda: [], 1.0, True)) == []
