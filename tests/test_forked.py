"""Work shared with a forked child: the same results as computed here alone, and every failure
of the child raised here with what it was doing."""

from __future__ import annotations

import multiprocessing
import os
import threading

import pytest

from roadweaver_sumo import forked

pytestmark = pytest.mark.skipif(not forked.can_fork(), reason="only where fork exists")


def test_map_shared_keeps_the_order_and_uses_a_child():
    items = list(range(11))
    pids = forked.map_shared(lambda k: (k * k, os.getpid()), items, name="squaring")
    assert [square for square, _ in pids] == [k * k for k in items]
    assert {pid for _, pid in pids[0::2]} == {os.getpid()}
    assert {pid for _, pid in pids[1::2]} - {os.getpid()}  # every other item: the child


def test_few_items_stay_in_this_process():
    pids = forked.map_shared(lambda k: os.getpid(), [1, 2, 3], name="ids", min_items=4)
    assert set(pids) == {os.getpid()}


def test_an_error_in_the_child_is_raised_here():
    def fail_on_odd(k):
        if k % 2:
            raise ValueError(f"item {k} is odd")
        return k

    with pytest.raises(ValueError, match="item 1 is odd"):
        forked.map_shared(fail_on_odd, [0, 1, 2, 3], name="checking")


def test_the_error_here_wins_and_the_child_is_collected_first():
    def fail_here():
        raise OSError(28, "No space left on device")

    def fail_there():
        raise ValueError("the child failed too")

    with pytest.raises(OSError, match="No space left"):
        forked.beside(fail_there, fail_here, name="writing")
    assert multiprocessing.active_children() == []


def test_a_child_that_dies_is_named():
    with pytest.raises(RuntimeError, match=r"the process writing map.xodr died \(exit code 3\)"):
        forked.beside(lambda: os._exit(3), lambda: None, name="writing map.xodr")


def test_a_result_that_cannot_be_sent_back_is_named():
    with pytest.raises(RuntimeError, match="linking dead ends: its result cannot be sent back"):
        forked.beside(lambda: threading.Lock(), lambda: None, name="linking dead ends")
