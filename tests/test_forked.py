"""Work shared with a forked child: the same results as computed here alone, and every failure
of the child raised here with what it was doing."""

from __future__ import annotations

import multiprocessing
import os
import threading

import pytest

from roadweaver_sumo import forked

pytestmark = pytest.mark.skipif(not forked.can_fork(), reason="only where fork exists")


def test_both_parts_are_computed_and_an_error_in_the_child_is_raised_here():
    here, there = forked.beside(lambda: os.getpid(), lambda: os.getpid(), name="ids")
    assert here == os.getpid() != there

    def fail_there():
        raise ValueError("the child's part failed")

    with pytest.raises(ValueError, match="the child's part failed"):
        forked.beside(fail_there, lambda: None, name="checking")


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
