"""The availability rule of ROS servers, on explicit time (no ROS): one failed check of a
server seen does not make it gone; failures in a row over the window do; one success brings
it back. Runs in .venv too."""

from __future__ import annotations

import pytest

from btcap.ros.availability import Availability


def checks(a: Availability, results: list[tuple[float, bool]]) -> list[bool]:
    return [a.check(ok, t) for t, ok in results]


def test_a_server_never_seen_is_not_there_and_comes_at_the_first_success() -> None:
    a = Availability(fails=3, window_s=1.0)
    assert not a.ready
    assert checks(a, [(0.0, False), (0.1, False), (0.2, True)]) == [False, False, True]


def test_one_failed_check_under_load_does_not_make_a_server_gone() -> None:
    a = Availability(fails=3, window_s=1.0)
    got = checks(a, [(0.0, True), (0.1, False), (0.2, True), (0.3, False), (0.4, True)])
    assert got == [True] * 5


def test_failures_in_a_row_count_only_once_the_window_passed() -> None:
    a = Availability(fails=3, window_s=1.0)
    a.check(True, 0.0)
    # three quick failures: not yet (0.3 s since the last success)
    assert checks(a, [(0.1, False), (0.2, False), (0.3, False)]) == [True] * 3
    assert checks(a, [(0.9, False), (1.0, False)]) == [True, False]
    assert a.check(True, 1.1)  # back at once


def test_one_failure_after_a_stalled_poller_is_not_enough() -> None:
    a = Availability(fails=3, window_s=1.0)
    a.check(True, 0.0)
    assert checks(a, [(5.0, False), (5.1, False)]) == [True, True]
    assert not a.check(False, 5.2)


def test_a_success_between_failures_starts_the_count_again() -> None:
    a = Availability(fails=2, window_s=0.0)
    assert checks(a, [(0.0, True), (1.0, False), (2.0, True), (3.0, False), (4.0, False)]) == [
        True,
        True,
        True,
        True,
        False,
    ]


@pytest.mark.parametrize(("fails", "window_s"), [(0, 1.0), (1, -1.0)])
def test_a_bad_rule_is_refused(fails: int, window_s: float) -> None:
    with pytest.raises(ValueError, match="fails >= 1 and window_s >= 0"):
        Availability(fails, window_s)
