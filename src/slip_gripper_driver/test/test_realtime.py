# SPDX-License-Identifier: Apache-2.0
"""realtime: thread scheduling fails soft and reports; GC freeze (no timing asserted)."""
from __future__ import annotations

import gc
import os
import threading

import pytest

from slip_gripper_driver.core import realtime
from slip_cell_common.core.param_schema import ParameterError
from slip_gripper_driver.core.realtime import RealtimeParams, ThreadTuning, freeze_gc


def _in_thread(tuning: ThreadTuning, name: str) -> bool:
    out: list[bool] = []
    thread = threading.Thread(target=lambda: out.append(tuning.apply()), name=name)
    thread.start()
    thread.join(5.0)
    return out[0]


def test_no_tuning_leaves_the_thread_normal() -> None:
    tuning = ThreadTuning(0, 0)
    assert _in_thread(tuning, 'reader')
    assert tuning.results == {'reader': 'normal'}
    assert tuning.take_failures() == []


def test_refused_fifo_falls_back_to_nice_and_reports_once(monkeypatch) -> None:
    def refuse(*_: object) -> None:
        raise PermissionError(1, 'Operation not permitted')
    monkeypatch.setattr(os, 'sched_setscheduler', refuse)
    monkeypatch.setattr(os, 'setpriority', lambda *_: None)
    tuning = ThreadTuning(priority=10, nice=5)
    assert not _in_thread(tuning, 'serial-reader')
    outcome = tuning.results['serial-reader']
    assert outcome.startswith('nice 5') and 'not permitted' in outcome
    failures = tuning.take_failures()
    assert len(failures) == 1 and 'SCHED_FIFO priority 10' in failures[0]
    assert tuning.take_failures() == []  # logged once


def test_refused_niceness_is_reported(monkeypatch) -> None:
    def refuse(*_: object) -> None:
        raise PermissionError(1, 'Operation not permitted')
    monkeypatch.setattr(os, 'setpriority', refuse)
    assert 'not permitted' in realtime.set_niceness(-5)


def test_params_validate() -> None:
    RealtimeParams().validate()
    with pytest.raises(ParameterError, match='priority'):
        RealtimeParams(priority=120).validate()


def test_freeze_gc_moves_live_objects_out_of_collection() -> None:
    try:
        frozen = freeze_gc(threshold_0=gc.get_threshold()[0])
        assert frozen > 0 and gc.get_freeze_count() == frozen
    finally:
        gc.unfreeze()
