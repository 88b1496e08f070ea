# SPDX-License-Identifier: Apache-2.0
"""Fixtures of the slip_cell_common tests."""
from __future__ import annotations

import os
import tty
from collections.abc import Iterator

import pytest


@pytest.fixture
def pty() -> Iterator[tuple[int, str]]:
    """A raw pseudo-terminal: (master fd, slave path); both ends closed afterwards."""
    master, slave = os.openpty()
    tty.setraw(slave)
    yield master, os.ttyname(slave)
    os.close(master)
    os.close(slave)
