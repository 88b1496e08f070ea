#!/usr/bin/env python3
"""Replay a recorded experiment through the estimator and HOLD controller cores (no DDS).

Prints how much faster than real time the cores process the bag's sensor streams (issue 8
target: a 60 s experiment at >= 200x real time). Bag reading and decoding are timed apart from
the core replay. Run by `make bench`; no assertions.

    tools/run_ros.sh .venv/bin/python bench/bench_replay.py [--bag bags/force_tracking]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from slip_control.core.contact import ContactProperties, ContactSource, FingerContact
from slip_control.core.contact_estimator import ContactEstimator, EstimationPhase
from slip_control.core.mode_switch import ModeRequest, build_controller
from slip_control.core.params import ContactEstimatorParams, SlipControllerParams
from slip_control.core.signals import SensorSnapshot
from slip_control.slip_msgs_conv import twist_from_msg, wrench_from_msg
from slip_cell_common.bag_io import bag_info, read_messages, stamp_s
from slip_cell_common.core import names

SENSORS = tuple(names.absolute(n) for n in (names.ft_wrench(1), names.ft_wrench(2),
                                            names.slip_twist(1), names.slip_twist(2)))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    root = Path(__file__).resolve().parents[1]
    parser.add_argument('--bag', default='', help='default: the longest bag in bags/ that has '
                        'both fingers\' wrench and twist topics')
    parser.add_argument('--quick', action='store_true', help='accepted for make bench')
    ns = parser.parse_args()
    if not ns.bag:
        candidates = []
        for path in sorted((root / 'bags').iterdir()) if (root / 'bags').is_dir() else []:
            if path.is_dir():
                info = bag_info(path)
                if set(SENSORS) <= {t.name for t in info.topics}:
                    candidates.append((info.duration_s, str(path)))
        ns.bag = max(candidates)[1] if candidates else ''
    if not ns.bag or not Path(ns.bag).is_dir():
        print('bench_replay: no bag with the sensor topics (run make bags)')
        return 0
    t0 = time.perf_counter()
    msgs = read_messages(ns.bag, list(SENSORS))
    events = sorted(((stamp_s(m), topic, m) for topic in SENSORS for _, m in msgs[topic]),
                    key=lambda e: e[0])
    t_read = time.perf_counter() - t0
    span = events[-1][0] - events[0][0]
    finger = FingerContact(mu_c=0.5, mu_s=0.5, mu_v=0.0, r=0.005, u=2.5e-5, mu_c_std=0.01,
                           r_std=1e-4, n_linear=50, n_static=5, n_rotational=50,
                           linear_valid=True, viscous_valid=False, static_valid=True,
                           rotational_valid=True)
    props = ContactProperties(finger, finger, ContactSource.ESTIMATED, 'bench')
    estimator = ContactEstimator(ContactEstimatorParams())
    params = SlipControllerParams()
    outcome = build_controller(ModeRequest(mode=4), props, params, events[0][0])
    assert outcome.ok, outcome.message
    controller = outcome.controller
    estimator.start(EstimationPhase.LINEAR, span / 2, events[0][0])
    # Conversion from messages to samples is part of the replay cost; decoding is not.
    t0 = time.perf_counter()
    snap = SensorSnapshot()
    steps = 0
    for t, topic, msg in events:
        k = 1 if topic.startswith('/finger_1') else 2
        if topic.endswith('wrench'):
            snap = snap.with_wrench(k, wrench_from_msg(msg))
        else:
            snap = snap.with_twist(k, twist_from_msg(msg))
            if k == 1:
                estimator.step(snap, t)
                controller.step(snap, t)
                steps += 1
    t_core = time.perf_counter() - t0
    print(f'{"bag":<28} {Path(ns.bag).name}')
    print(f'{"recorded span":<28} {span:8.2f} s, {len(events)} sensor messages, {steps} steps')
    print(f'{"read + decode":<28} {t_read:8.3f} s')
    print(f'{"core replay":<28} {t_core:8.3f} s  ->  {span / t_core:8.0f} x real time')
    print(f'{"read + decode + replay":<28} {t_read + t_core:8.3f} s  ->  '
          f'{span / (t_read + t_core):8.0f} x real time')
    return 0


if __name__ == '__main__':
    sys.exit(main())
