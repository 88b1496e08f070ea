# SPDX-License-Identifier: Apache-2.0
"""Net F/T RDT codecs, sequence tracking, status, units, netftapi2.xml and host-side bias."""
from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from slip_cell_common.core.monitors import Level
from slip_gripper_driver.core.netft import (RECORD_SIZE, BiasAccumulator, BiasParams, BiasState,
                                            DatagramError, ForceTorqueScale, FtParams,
                                            RdtCommand, SequenceTracker, SeqVerdict,
                                            decode_datagram, decode_request, decode_status,
                                            encode_record, encode_request, force_unit_factor,
                                            parse_netft_config, torque_unit_factor)
from slip_cell_common.core.param_schema import ParameterError, flatten


def test_request_layout_is_big_endian_8_bytes() -> None:
    data = encode_request(RdtCommand.START_REALTIME, 0)
    assert data == b'\x12\x34\x00\x02\x00\x00\x00\x00'
    assert encode_request(RdtCommand.SET_BIAS, 10) == b'\x12\x34\x00\x42\x00\x00\x00\x0a'
    assert decode_request(encode_request(RdtCommand.STOP, 7)) == (0, 7)
    with pytest.raises(DatagramError):
        decode_request(b'\x43\x21' + data[2:])
    with pytest.raises(DatagramError):
        decode_request(data[:7])


def test_record_layout_and_signed_counts() -> None:
    rec = encode_record(1, 2, 0x80010000, (-1, 2, -3_000_000, 4, -5, 2**31 - 1))
    assert len(rec) == 36
    assert rec[:12] == struct.pack('>III', 1, 2, 0x80010000)
    (got,) = decode_datagram(rec)
    assert got.rdt_sequence == 1 and got.ft_sequence == 2 and got.status == 0x80010000
    assert got.counts == (-1, 2, -3_000_000, 4, -5, 2**31 - 1)
    assert len(decode_datagram(rec * 4)) == 4  # buffered mode


def test_truncated_and_garbage_datagrams_are_rejected() -> None:
    rng = np.random.default_rng(0)
    rec = encode_record(1, 1, 0, (0,) * 6)
    for n in (0, 1, 20, 35, 37, 71):
        with pytest.raises(DatagramError):
            decode_datagram((rec * 3)[:n])
    accepted = 0
    for _ in range(20000):
        data = rng.integers(0, 256, size=int(rng.integers(0, 200)), dtype=np.uint8).tobytes()
        try:
            records = decode_datagram(data)
        except DatagramError:
            assert len(data) % RECORD_SIZE != 0 or not data
            continue
        accepted += 1
        assert len(records) * RECORD_SIZE == len(data)
    assert accepted > 0


def test_sequence_tracker_loss_duplicates_reorder_and_wrap() -> None:
    tr = SequenceTracker()
    top = 2**32 - 2
    seqs = [top, top + 1, 0, 1, 1, 4, 3, 5]  # wrap, duplicate, gap of 2, late 3
    verdicts = [tr.update(s % 2**32, s % 2**32) for s in seqs]
    assert verdicts == [SeqVerdict.FIRST, SeqVerdict.NEW, SeqVerdict.NEW, SeqVerdict.NEW,
                        SeqVerdict.DUPLICATE, SeqVerdict.NEW, SeqVerdict.OLD, SeqVerdict.NEW]
    assert (tr.lost, tr.duplicates, tr.out_of_order, tr.accepted) == (2, 1, 1, 6)
    assert tr.ft_stalls == 0 and tr.ft_restarts == 0


def test_sequence_tracker_resyncs_after_a_box_restart() -> None:
    tr = SequenceTracker(resync_after=4)
    for s in range(1000, 1010):
        tr.update(s, s)
    verdicts = [tr.update(s, s) for s in range(0, 6)]  # the box restarted its counters
    assert verdicts[:3] == [SeqVerdict.OLD] * 3 and verdicts[3] == SeqVerdict.RESYNC
    assert verdicts[4:] == [SeqVerdict.NEW] * 2 and tr.resyncs == 1 and tr.lost == 0


def test_ft_sequence_stalls_and_restarts() -> None:
    tr = SequenceTracker()
    tr.update(1, 100)
    tr.update(2, 100)  # measurement did not advance
    tr.update(3, 50)  # went backwards: device restart
    assert tr.ft_stalls == 1 and tr.ft_restarts == 1


@pytest.mark.parametrize('word, level, text', [
    (0, Level.OK, 'healthy'),
    (0x80010000, Level.WARN, 'monitor condition latched'),
    (0x80020000, Level.ERROR, 'saturation'),
    (0x00100000, Level.ERROR, 'RDT communication error'),
    (0x80000000, Level.ERROR, 'error summary'),
    (0x00000004, Level.ERROR, 'other bits'),
])
def test_status_word_decoding(word: int, level: Level, text: str) -> None:
    info = decode_status(word)
    assert info.level == level and text in info.text


@pytest.mark.parametrize('unit, factor', [
    ('N', 1.0), ('n', 1.0), ('lbf', 4.4482216152605), ('klbf', 4448.2216152605),
    ('kgf', 9.80665), ('kN', 1000.0), (' LBF ', 4.4482216152605)])
def test_force_units(unit: str, factor: float) -> None:
    assert force_unit_factor(unit) == factor


@pytest.mark.parametrize('unit, factor', [
    ('N-m', 1.0), ('Nm', 1.0), ('N m', 1.0), ('N·m', 1.0), ('N-mm', 0.001),
    ('lbf-in', 0.1129848290276167), ('lbf-ft', 1.3558179483314004), ('kgf-cm', 0.0980665),
    ('kN-m', 1000.0)])
def test_torque_units(unit: str, factor: float) -> None:
    assert torque_unit_factor(unit) == factor


def test_unknown_units_and_bad_counts_are_rejected() -> None:
    with pytest.raises(ValueError, match='known'):
        force_unit_factor('stone')
    with pytest.raises(ValueError):
        ForceTorqueScale(0.0, 1e6)
    with pytest.raises(ValueError):
        ForceTorqueScale(1e6, math.nan)


def test_scale_to_si() -> None:
    scale = ForceTorqueScale(1_000_000, 1_000_000, 'lbf', 'lbf-in')
    w = scale.to_si((1_000_000, 0, -2_000_000, 1_000_000, 0, 0))
    assert w[0] == pytest.approx(4.4482216152605) and w[2] == pytest.approx(-8.896443230521)
    assert w[3] == pytest.approx(0.1129848290276167)
    assert scale.to_counts(w) == (1_000_000, 0, -2_000_000, 1_000_000, 0, 0)


SAMPLE_XML = """<?xml version="1.0" encoding="utf-8"?>
<netft><setserial>FT01234</setserial><comrdte>true</comrdte><comrdtrate>1000</comrdtrate>
<runstat>0</runstat><cfgcpf>1000000</cfgcpf><cfgcpt>1000000</cfgcpt>
<scfgfu>N</scfgfu><scfgtu>Nm</scfgtu><cfgmr>40;40;120;2;2;2</cfgmr>
<netip>192.168.56.6</netip></netft>"""


def test_parse_netft_config() -> None:
    cfg = parse_netft_config(SAMPLE_XML)
    assert cfg.scale == ForceTorqueScale(1e6, 1e6, 'N', 'Nm')
    assert cfg.rdt_rate_hz == 1000.0 and cfg.rdt_enabled is True
    assert cfg.values['netip'] == '192.168.56.6' and cfg.values['cfgmr'] == '40;40;120;2;2;2'
    with pytest.raises(ValueError, match='cfgcpt'):
        parse_netft_config(SAMPLE_XML.replace('<cfgcpt>1000000</cfgcpt>', ''))
    with pytest.raises(ValueError, match='not valid XML'):
        parse_netft_config('<netft><cfgcpf>')
    with pytest.raises(ValueError, match='unknown torque unit'):
        parse_netft_config(SAMPLE_XML.replace('Nm', 'foot-pound'))


def test_bias_accumulator_window_settle_and_min_samples() -> None:
    acc = BiasAccumulator(duration_s=0.1, min_samples=50, settle_samples=2)
    assert acc.add(0.0, (1.0,) * 6) is None  # unbiased: nothing to publish as biased
    acc.start(0.0)
    acc.add(0.001, (100.0,) * 6)  # settle samples are skipped
    acc.add(0.002, (100.0,) * 6)
    for k in range(101):  # 0.1 s window at 1 kHz
        acc.add(0.003 + k * 0.001, (1.0, 2.0, 3.0, 0.1, 0.2, 0.3))
    assert acc.state == BiasState.COLLECTING
    biased = acc.add(0.2, (1.5, 2.0, 3.0, 0.1, 0.2, 0.3))
    assert acc.state == BiasState.DONE and acc.biased
    assert biased == pytest.approx((0.5, 0.0, 0.0, 0.0, 0.0, 0.0))
    acc.start(1.0)  # too few samples arrive: fails, previous offsets kept
    for k in range(10):
        acc.add(1.0 + k * 0.02, (9.0,) * 6)
    acc.add(1.3, (9.0,) * 6)
    assert acc.state == BiasState.FAILED and 'samples' in acc.message
    assert acc.offsets == pytest.approx((1.0, 2.0, 3.0, 0.1, 0.2, 0.3))
    acc.start(2.0)
    assert acc.poll(2.3) == BiasState.COLLECTING
    assert acc.poll(2.7) == BiasState.FAILED  # no samples at all


def test_ft_params_require_counts_without_config_read() -> None:
    FtParams().validate()
    with pytest.raises(ParameterError, match='required'):
        FtParams(read_config=False).validate()
    FtParams(read_config=False, counts_per_force=1e6, counts_per_torque=1e6).validate()
    with pytest.raises(ParameterError, match='unknown force unit'):
        FtParams(force_unit='stone').validate()
    flat = flatten(FtParams())
    assert flat['finger_1.address'] == '192.168.56.6'
    assert flat['finger_2.address'] == '192.168.56.5'
    BiasParams().validate()
    assert BiasParams().accumulator().min_samples == 50
