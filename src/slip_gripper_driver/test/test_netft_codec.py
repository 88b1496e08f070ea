# SPDX-License-Identifier: Apache-2.0
"""Net F/T RDT codecs, sequence tracking, status, units, netftapi2.xml and host-side bias."""
from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from slip_cell_common.core.monitors import Level
from slip_gripper_driver.core.ft_bias import BiasAccumulator, BiasParams, BiasState
from slip_gripper_driver.core.ft_scale import (ForceTorqueScale, force_unit_factor,
                                               torque_unit_factor)
from slip_gripper_driver.core.netft_config import parse_netft_config
from slip_gripper_driver.core.ft_validity import (UNCHECKED, RecordFlaw, merge_limits,
                                                  record_flaw)
from slip_gripper_driver.core.netft_params import (FtFinger1Params, FtFinger2Params, FtParams,
                                                   FtRangeParams, FtStreamParams)
from slip_gripper_driver.core.netft_status import decode_status, is_error_status
from slip_gripper_driver.core.rdt_codec import (RECORD_SIZE, DatagramError, RdtCommand,
                                                decode_datagram, decode_request, encode_record,
                                                encode_request)
from slip_gripper_driver.core.rdt_sequence import SeqVerdict, SequenceTracker
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


def test_sequence_tracker_resyncs_when_the_numbering_jumps_back_without_a_new_stream() -> None:
    tr = SequenceTracker(resync_after=4)
    for s in range(1000, 1010):
        tr.update(s, s)
    verdicts = [tr.update(s, 2000 + s) for s in range(500, 506)]  # not 1, no start request
    assert verdicts[:3] == [SeqVerdict.OLD] * 3 and verdicts[3] == SeqVerdict.RESYNC
    assert verdicts[4:] == [SeqVerdict.NEW] * 2 and tr.resyncs == 1 and tr.lost == 0
    assert tr.new_streams == 0 and tr.ft_restarts == 0


def test_a_new_stream_numbered_from_1_is_accepted_at_once() -> None:
    """Real box: every start request restarts rdt_sequence at 1 (ft_sequence continues)."""
    tr = SequenceTracker()
    tr.expect_new_stream()
    assert [tr.update(s, 100 + s) for s in (1, 2, 3)] == \
        [SeqVerdict.FIRST, SeqVerdict.NEW, SeqVerdict.NEW]
    for s in range(4, 5000):
        tr.update(s, 100 + s)
    # A start request re-sent (silence, device bias): the next stream starts at 1 again.
    tr.expect_new_stream()
    assert tr.update(4999 + 1, 5100) == SeqVerdict.NEW  # still in flight from the old one
    assert [tr.update(s, 5200 + s) for s in (1, 2, 3)] == \
        [SeqVerdict.NEW_STREAM, SeqVerdict.NEW, SeqVerdict.NEW]
    # A new stream whose first two records were lost, after a start request.
    tr.expect_new_stream()
    assert tr.update(3, 9000) == SeqVerdict.NEW_STREAM
    # Record 1 opens a stream even without a known start request (another start elsewhere).
    for s in range(4, 100):
        tr.update(s, 9000 + s)
    assert tr.update(1, 9200) == SeqVerdict.NEW_STREAM
    assert (tr.new_streams, tr.lost, tr.out_of_order, tr.resyncs) == (3, 2, 0, 0)
    assert tr.ft_restarts == 0 and not tr.restarted


def test_new_stream_across_the_wrap_and_late_records_within_a_stream() -> None:
    tr = SequenceTracker()
    for s in range(2**32 - 200, 2**32 - 100):
        tr.update(s, s)
    tr.expect_new_stream()
    assert tr.update(2, 2**32 - 99) == SeqVerdict.NEW_STREAM  # looks "newer" across the wrap
    assert tr.lost == 1
    assert [tr.update(s, 2**32 - 99 + s) for s in (4, 3, 5)] == \
        [SeqVerdict.NEW, SeqVerdict.OLD, SeqVerdict.NEW]  # 3 is late within the stream
    assert tr.out_of_order == 1
    # Without a start request, a short step across the wrap continues the stream (loss).
    tr = SequenceTracker()
    tr.update(2**32 - 2, 10)
    assert tr.update(2, 11) == SeqVerdict.NEW and tr.lost == 3


def test_device_restart_is_flagged_on_the_record_that_shows_it() -> None:
    tr = SequenceTracker()
    for s in range(1, 200):
        tr.update(s, 7000 + s)
    tr.expect_new_stream()
    assert tr.update(1, 3) == SeqVerdict.NEW_STREAM and tr.restarted  # ft_sequence went back
    assert tr.update(2, 4) == SeqVerdict.NEW and not tr.restarted
    assert tr.ft_restarts == 1


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
    assert is_error_status(word) == (level == Level.ERROR)


def test_record_flaws_status_and_measuring_range() -> None:
    limits = merge_limits((0.0, 0.0, 100.0, 0.0, 0.0, 0.0), (40.0, 40.0, 120.0, 2.0, 2.0, 2.0))
    assert limits == (40.0, 40.0, 100.0, 2.0, 2.0, 2.0)  # a parameter entry wins
    assert merge_limits((0.0,) * 6, None) == UNCHECKED
    ok = (1.0, -2.0, -99.0, 0.1, 0.0, -1.9)
    assert record_flaw(0, ok, limits) == RecordFlaw.NONE
    assert record_flaw(0x80010000, ok, limits) == RecordFlaw.NONE  # latched monitor: warning
    assert record_flaw(0x80020000, ok, limits) == RecordFlaw.STATUS_ERROR
    assert record_flaw(0, (1.0, -2.0, -100.5, 0.1, 0.0, 0.0), limits) == RecordFlaw.OUT_OF_RANGE
    assert record_flaw(0, (0.0, 0.0, 0.0, 0.0, 2.1, 0.0), limits) == RecordFlaw.OUT_OF_RANGE
    assert record_flaw(0, (1e9,) * 6, UNCHECKED) == RecordFlaw.NONE
    with pytest.raises(ValueError):
        merge_limits((0.0,) * 5, None)


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
    assert cfg.measuring_range == (40.0, 40.0, 120.0, 2.0, 2.0, 2.0)
    lbf = parse_netft_config(SAMPLE_XML.replace('<scfgfu>N</scfgfu>', '<scfgfu>lbf</scfgfu>'))
    assert lbf.measuring_range is not None
    assert lbf.measuring_range[2] == pytest.approx(120 * 4.4482216152605)
    assert parse_netft_config(SAMPLE_XML.replace('40;40;120;2;2;2', '40;40')) \
        .measuring_range is None
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


def _biased_at(acc: BiasAccumulator, fz: float) -> None:
    acc.start(0.0)
    for k in range(200):
        acc.add(0.001 * k, (0.0, 0.0, fz, 0.0, 0.0, 0.0))
    assert acc.state == BiasState.DONE


def test_a_device_bias_window_averages_only_the_new_stream() -> None:
    """After 0x0042 the old stream's records (old tare, +2.5 N) are not averaged; the window
    opens with the first record of the new stream."""
    acc = BiasAccumulator(duration_s=0.1, min_samples=50, settle_samples=2)
    _biased_at(acc, 2.5)
    acc.start(1.0, after_device_bias=True)
    for k in range(80):  # queued records of the old stream, read late
        acc.add(1.0 + 1e-5 * k, (0.0, 0.0, 2.5, 0.0, 0.0, 0.0))
    assert acc.state == BiasState.COLLECTING
    acc.add(1.01, (0.0, 0.0, 0.01, 0.0, 0.0, 0.0), new_stream=True)
    for k in range(1, 150):  # the tared stream
        acc.add(1.01 + 0.001 * k, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    assert acc.state == BiasState.DONE and not acc.tare_lost
    assert acc.offsets == pytest.approx((0.0,) * 6, abs=1e-3)


def test_a_failed_device_bias_window_drops_the_offsets_it_no_longer_fits() -> None:
    acc = BiasAccumulator(duration_s=0.1, min_samples=50, settle_samples=2)
    _biased_at(acc, 2.5)
    acc.start(1.0, after_device_bias=True)
    for k in range(100):  # the box keeps its old stream: no new stream ever starts
        acc.add(1.0 + 0.001 * k, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    assert acc.poll(1.7) == BiasState.FAILED
    assert 'started no new stream' in acc.message and 'no longer applies' in acc.message
    assert acc.tare_lost and not acc.biased
    # A host window that fails keeps the offsets (nothing changed in the box).
    _biased_at(acc, 2.5)
    acc.start(2.0)
    assert acc.poll(2.7) == BiasState.FAILED and acc.biased and not acc.tare_lost
    # A box restart during the wait ends it; a new-stream record after that opens nothing.
    acc.start(3.0, after_device_bias=True)
    acc.clear('bias lost after device restart')
    acc.add(3.01, (0.0,) * 6, new_stream=True)
    assert acc.state == BiasState.IDLE and acc.message == 'bias lost after device restart'


def test_ft_params_require_counts_without_config_read() -> None:
    FtParams().validate()
    with pytest.raises(ParameterError, match='required'):
        FtParams(stream=FtStreamParams(read_config=False)).validate()
    with pytest.raises(ParameterError, match='required'):
        FtStreamParams(read_config=False).validate()
    FtStreamParams(read_config=False, counts_per_force=1e6, counts_per_torque=1e6).validate()
    with pytest.raises(ParameterError, match='unknown force unit'):
        FtParams(stream=FtStreamParams(force_unit='stone')).validate()
    flat = flatten(FtParams())
    assert flat['read_config'] is True and flat['start_retries'] == 10
    assert flat['finger_1.address'] == '192.168.56.6'
    assert flat['finger_2.address'] == '192.168.56.5'
    assert flat['http_port'] == 80 and flat['publish_on_error'] is False
    assert flat['measuring_range.fz'] == 0.0 and flat['finger_2.port'] == 0
    limits = FtStreamParams(measuring_range=FtRangeParams(fz=100.0)).measuring_range.limits()
    assert merge_limits(limits, (40.0, 40.0, 120.0, 2.0, 2.0, 2.0)) == \
        (40.0, 40.0, 100.0, 2.0, 2.0, 2.0)


def test_per_box_ports_default_to_the_shared_ones() -> None:
    ft = FtParams()
    assert [tuple(b) for b in ft.boxes()] == [(1, '192.168.56.6', 49152, 80),
                                               (2, '192.168.56.5', 49152, 80)]
    two_on_one_host = FtParams(finger_1=FtFinger1Params('10.0.0.2', 50001, 8081),
                               finger_2=FtFinger2Params('10.0.0.2', 50002, 8082),
                               stream=FtStreamParams(http_port=8080))
    two_on_one_host.validate()
    assert [tuple(b) for b in two_on_one_host.boxes()] == [(1, '10.0.0.2', 50001, 8081),
                                                            (2, '10.0.0.2', 50002, 8082)]
    with pytest.raises(ParameterError, match='both boxes at 10.0.0.2:49152'):
        FtParams(finger_1=FtFinger1Params('10.0.0.2'),
                 finger_2=FtFinger2Params('10.0.0.2')).validate()
    BiasParams().validate()
    assert BiasParams().accumulator().min_samples == 50
