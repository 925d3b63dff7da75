"""Taxel stamps from the hub's clock: the estimator on synthetic receive times, and the real serial
backend over a pty with the hub's frames arriving in bursts (the acceptance test)."""
import re
import threading
import time
from dataclasses import replace

import numpy as np
import pytest

from prisma_common.diagnostics import OK
from prisma_common.hand import FINGERS
from prisma_tactile_driver import hub_clock
from prisma_tactile_driver.hub_clock import HubClockConfig, HubClockState, reanchor, update
from prisma_tactile_driver.protocol import encode_frame
from prisma_tactile_driver.pty_hub import PtyHubPort
from prisma_tactile_driver.serial_backend import SerialHubBackend
from prisma_tactile_driver.tactile_driver_core import TactileHub
from prisma_testing.repo_paths import ROOT

MS = 1_000_000
PERIOD = 10 * MS
T0 = 1_700_000_000 * 1_000_000_000  # host time of the hub's first frame (a wall-clock epoch)
FIRMWARE = ROOT / "firmware" / "prisma_fingertip_hub" / "prisma_fingertip_hub.ino"


def receive_times(n, *, skew=0.0, seed=0, latency_ms=1.0, flush_ms=None, first_seq=0):
    """Frame k leaves the hub at k * period * (1 + skew) and reaches the host after 3 ms plus an
    exponential latency; with flush_ms, an adapter delivers whatever arrived at jittered instants
    about flush_ms apart. Returns (sequences, receive_ns, truth_ns): truth = send + 3 ms."""
    rng = np.random.default_rng(seed)
    send = np.arange(n) * PERIOD * (1 + skew)
    arrive = send + 3 * MS + rng.exponential(latency_ms * MS, n)
    if flush_ms is not None:
        flushes = np.cumsum(flush_ms * MS + rng.uniform(0, 2 * MS, int(arrive[-1] / (flush_ms * MS)) + 10))
        arrive = flushes[np.searchsorted(flushes, arrive)]
    sequences = (first_seq + np.arange(n)) % 65536
    return sequences, T0 + np.round(arrive).astype(np.int64), T0 + np.round(send + 3 * MS).astype(np.int64)


def drain(sequences, received, state=None, config=hub_clock.DEFAULT_CONFIG):
    """Feed frames as a driver would: each read drains everything received at one instant."""
    state = state or HubClockState()
    stamps, results = [], []
    starts = np.flatnonzero(np.diff(received, prepend=received[0] - 1))
    for start, end in zip(starts, list(starts[1:]) + [len(received)]):
        result = update(state, [int(s) for s in sequences[start:end]], int(received[start]), config)
        state = result.state
        stamps += result.stamps_ns
        results.append(result)
    return np.array(stamps, dtype=np.int64), state, results


def test_firmware_rate_is_the_estimators_nominal_period():
    rate = int(re.search(r"#define HUB_RATE_HZ (\d+)", FIRMWARE.read_text()).group(1))
    assert rate == hub_clock.FIRMWARE_RATE_HZ == 1e9 / hub_clock.NOMINAL_PERIOD_NS


def test_frames_drained_together_get_evenly_spaced_stamps_ending_at_the_receive_time():
    result = update(HubClockState(), [7, 8, 9, 10, 11], T0)
    assert result.stamps_ns == (T0 - 40 * MS, T0 - 30 * MS, T0 - 20 * MS, T0 - 10 * MS, T0)
    assert result.anchored and result.dropped == 0
    assert result.state.last_sequence == 11 and result.state.anchors == 1


def test_jittered_latency_is_filtered_out():
    sequences, received, truth = receive_times(3000, latency_ms=2.0, seed=1)
    stamps, state, _ = drain(sequences, received)
    error = stamps - truth
    # the first frame is anchored at its own receive time; lower latencies pull the line down
    assert error[0] == received[0] - truth[0] > 0
    assert np.abs(error[100:]).max() < 0.5 * MS  # after 1 s
    assert np.abs(error[1000:]).max() < 0.2 * MS  # after 10 s
    spacing = np.diff(stamps)
    assert np.all(np.abs(spacing - PERIOD) <= 0.2 * MS)  # slewed by at most 2 % of a period
    assert state.dropped == 0 and state.anchors == 1
    # the raw receive times would have been up to ~20 ms off
    assert (received - truth).max() > 10 * MS


def test_bursts_of_five_every_50_ms_get_distinct_stamps_10_ms_apart():
    n = 2000
    sequences = np.arange(n)
    truth = T0 + np.arange(n) * PERIOD
    # the adapter flushes 0-1 ms after every fifth frame: five frames per read
    delay = np.random.default_rng(2).uniform(0, MS, n // 5)
    received = np.repeat(truth[4::5] + np.round(delay).astype(np.int64), 5)
    stamps, state, results = drain(sequences, received)
    assert len(results) == n // 5 and all(len(r.stamps_ns) == 5 for r in results)
    spacing = np.diff(stamps)
    assert np.all(np.abs(spacing - PERIOD) < 1 * MS)
    assert np.all(spacing > 0) and len(set(stamps.tolist())) == n
    assert np.abs(stamps[500:] - truth[500:]).max() < 1 * MS


@pytest.mark.parametrize("skew", [100e-6, -100e-6])
@pytest.mark.parametrize("delivery", [{"latency_ms": 2.0}, {"flush_ms": 4}], ids=["jitter", "bursts"])
def test_100_ppm_drift_over_ten_minutes_stays_within_1_ms(skew, delivery):
    n = 60_000  # 10 minutes at 100 Hz
    sequences, received, truth = receive_times(n, skew=skew, seed=3, **delivery)
    stamps, state, _ = drain(sequences, received)
    error = stamps - truth
    assert np.abs(error[1000:]).max() < 1 * MS  # converged after 10 s, held for 10 minutes
    assert abs(state.skew - skew) < 20e-6  # the period estimate follows the hub's oscillator
    assert state.anchors == 1 and state.dropped == 0 and state.restarts == 0
    # without the drift correction the nominal period would be 60 ms off by the end
    assert abs(n * PERIOD * skew) > 50 * MS


def test_a_ceramic_resonator_half_a_percent_off_is_tracked():
    sequences, received, truth = receive_times(6000, skew=0.005, seed=4)
    stamps, state, _ = drain(sequences, received)
    assert abs(state.skew - 0.005) < 20e-6
    assert np.abs(stamps[1500:] - truth[1500:]).max() < 1 * MS


def test_sequence_wraps_around_without_a_gap_or_restart():
    sequences, received, truth = receive_times(2000, first_seq=65_000, seed=5)
    assert sequences[535] == 65_535 and sequences[536] == 0
    stamps, state, _ = drain(sequences, received)
    assert state.dropped == 0 and state.restarts == 0 and state.anchors == 1
    assert np.all(np.abs(np.diff(stamps) - PERIOD) <= 0.2 * MS)
    assert np.abs(stamps[1000:] - truth[1000:]).max() < 0.5 * MS


def test_a_gap_of_seven_frames_counts_seven_dropped():
    state = update(HubClockState(), [100], T0).state
    for seq in range(101, 110):
        state = update(state, [seq], T0 + (seq - 100) * PERIOD).state
    # 110..116 never arrive; 117 and 118 come in one read
    result = update(state, [117, 118], T0 + 18 * PERIOD)
    assert result.dropped == 7 and result.state.dropped == 7
    assert result.stamps_ns == (T0 + 17 * PERIOD, T0 + 18 * PERIOD)
    assert not result.anchored
    # across the wrap too, and inside one read
    wrapped = update(HubClockState(), [65_534, 65_535, 3], T0)
    assert wrapped.dropped == 3 and wrapped.stamps_ns[-1] - wrapped.stamps_ns[-2] == 4 * PERIOD


def test_a_hub_restart_reanchors_on_the_new_sequence():
    before_seq, before_rx, _ = receive_times(3000, seed=6)
    stamps, state, _ = drain(before_seq, before_rx)
    # the hub resets (1.5 s boot) and counts from 0 again
    after_seq, after_rx, after_truth = receive_times(3000, seed=7)
    boot = int(before_rx[-1]) + 1_500 * MS - T0
    after_rx, after_truth = after_rx + boot, after_truth + boot
    after, state, results = drain(after_seq, after_rx, state)
    assert results[0].anchored and state.restarts == 1 and state.anchors == 2
    assert state.dropped == 0  # a restart is not a gap
    assert after[0] > stamps[-1] + 1_000 * MS
    assert np.abs(after[1000:] - after_truth[1000:]).max() < 0.2 * MS
    # a restart inside one read: each part on its own anchor
    split = update(state, [3000, 3001, 0, 1], int(after_rx[-1]) + 20 * MS)
    assert split.anchored and split.state.restarts == 2
    assert split.stamps_ns[-2:] == (int(after_rx[-1]) + 10 * MS, int(after_rx[-1]) + 20 * MS)


def test_reconnect_reanchors_but_keeps_the_period_estimate():
    sequences, received, _ = receive_times(6000, skew=0.003, seed=8)
    _, state, _ = drain(sequences, received)
    fresh = reanchor(state)
    assert fresh.anchor_ns is None and fresh.last_sequence is None and fresh.skew == state.skew
    result = update(fresh, [4000, 4001], T0 + 200_000 * MS)
    assert result.anchored and result.dropped == 0
    assert result.stamps_ns[1] - result.stamps_ns[0] == round(PERIOD * (1 + state.skew))


def test_a_jump_the_clock_cannot_explain_reanchors():
    sequences, received, _ = receive_times(1000, seed=9)
    _, state, _ = drain(sequences, received)
    last = int(received[-1])
    # 20,000 frames ahead (200 s) only 30 ms later: the sequence cannot be trusted as a clock
    jump = update(state, [(999 + 20_000) % 65536], last + 30 * MS)
    assert jump.anchored and jump.stamps_ns == (last + 30 * MS,)
    # a hub that stopped counting for 2 s (no sensor answered): late frames re-anchor once the
    # lateness has lasted late_confirm_ns, not on the first late read
    state = jump.state
    seq, now = 20_999, last + 30 * MS
    anchored_at = None
    for i in range(1, 200):
        now += PERIOD + (2_000 * MS if i == 1 else 0)
        result = update(state, [(seq + i) % 65536], now)
        state = result.state
        if result.anchored:
            anchored_at = now
            assert result.stamps_ns == (now,)
            break
    assert anchored_at is not None
    assert 500 * MS <= anchored_at - (last + 30 * MS + 2_010 * MS) < 520 * MS


def test_a_host_stall_is_absorbed_without_reanchoring():
    sequences, received, truth = receive_times(3000, seed=10)
    received = received.copy()
    received[1500:1530] = received[1529]  # the driver did not read for 300 ms
    stamps, state, _ = drain(sequences, received)
    assert state.anchors == 1
    assert np.all(np.abs(np.diff(stamps) - PERIOD) <= 0.2 * MS)
    assert np.abs(stamps[1000:] - truth[1000:]).max() < 0.2 * MS


def test_update_is_pure():
    state = update(HubClockState(), [1, 2, 3], T0).state
    before = replace(state)
    update(state, [4, 5], T0 + 20 * MS)
    assert state == before


@pytest.mark.parametrize("field, value", [("period_ns", 0), ("window_frames", 0), ("slew", 1.5),
                                          ("max_skew", -0.1), ("min_fit_windows", 99)])
def test_config_is_validated_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        HubClockConfig(**{field: value})


# ---- the serial backend over a pty --------------------------------------------------------------
def write_bursts(port, n_bursts, counts, written, errors, burst=5, every_s=0.05):
    """The hub's frames, five at a time every 50 ms of wall time (what an adapter that buffers
    50 ms delivers); `written` gets each burst's scheduled wall time (a late write keeps it)."""
    try:
        start, start_wall = time.monotonic(), time.time_ns()
        for b in range(n_bursts):
            delay = start + b * every_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            seqs = range(b * burst, (b + 1) * burst)
            data = b"".join(encode_frame(s, counts[s % len(counts)]) for s in seqs)
            written.append(start_wall + round(b * every_s * 1e9))
            port.write(data)
    except Exception as exc:  # surfaced by the test
        errors.append(exc)


def test_bursts_over_a_pty_are_stamped_10_ms_apart(tmp_path):
    """Acceptance: the hub's frames arrive in bursts of 5 every 50 ms; the published stamps are
    10 ms apart within 1 ms, distinct and increasing."""
    port = PtyHubPort(tmp_path / "ttyHUB")
    port.open()
    backend = SerialHubBackend(str(port.link_path), 1_000_000, read_timeout_s=0.0)
    hub = TactileHub(backend, FINGERS)
    rng = np.random.default_rng(11)
    counts = [rng.integers(0, 4096, (5, 9)) for _ in range(7)]
    n_bursts = 60  # 3 s, 300 frames
    try:
        assert hub.poll(time.time_ns()) == []  # open first: pyserial flushes input on open
        written, errors = [], []
        writer = threading.Thread(target=write_bursts, args=(port, n_bursts, counts, written, errors), daemon=True)
        writer.start()
        thumb, polls = [], []  # (frame, poll stamp) of the thumb, one per hub frame
        deadline = time.monotonic() + 60
        while len(thumb) < 5 * n_bursts:
            assert time.monotonic() < deadline and not errors, errors
            now = time.time_ns()  # the node polls at serial_poll_hz (500 Hz) with its clock's now
            for frame in hub.poll(now):
                if frame.finger == "thumb":
                    thumb.append(frame)
                    polls.append(now)
            time.sleep(0.002)
        writer.join(5)
    finally:
        port.close()
        hub.close()

    stamps = np.array([f.stamp_ns for f in thumb])
    np.testing.assert_array_equal([f.counts for f in thumb], [counts[s % 7][0] for s in range(5 * n_bursts)])
    # bursts were drained together: far fewer distinct poll times than frames...
    assert len(set(polls)) <= 5 * n_bursts // 2
    # ...yet every frame has its own stamp, 10 ms after the one before
    spacing = np.diff(stamps)
    assert np.all(spacing > 0) and len(set(stamps.tolist())) == len(stamps)
    assert np.all(np.abs(spacing - 10 * MS) < 1 * MS), spacing[np.abs(spacing - 10 * MS) >= 1 * MS]
    # anchored to host time: the last frame of each burst is stamped near when it was due
    lag = stamps[4::5] - np.array(written)
    assert np.all(np.abs(lag) < 50 * MS), lag
    status = {s.name: s for s in hub.diagnostics(time.time_ns())}["tactile_driver: hub"]
    assert status.values["missed_frames"] == "0" and status.values["stamp_anchors"] == "1"
    assert status.values["port"] == str(port.link_path)


def test_dropped_frames_show_in_the_hub_diagnostics(tmp_path):
    port = PtyHubPort(tmp_path / "ttyHUB")
    port.open()
    backend = SerialHubBackend(str(port.link_path), 1_000_000, read_timeout_s=0.0)
    hub = TactileHub(backend, ["index"])
    counts = np.arange(45).reshape(5, 9) * 90
    try:
        hub.poll(T0)
        port.write(b"".join(encode_frame(s, counts) for s in [*range(0, 10), *range(17, 20)]))
        frames = []
        deadline = time.monotonic() + 10
        while len(frames) < 13:
            assert time.monotonic() < deadline
            frames += hub.poll(T0 + 500 * MS)
            time.sleep(0.002)
        stamps = [f.stamp_ns for f in frames]
        # the seven missing frames keep their place in the hub's time line
        assert stamps[10] - stamps[9] == 8 * PERIOD
        assert stamps[-1] == T0 + 500 * MS
        status = hub.diagnostics(T0 + 510 * MS)[0]
        assert status.level == OK
        assert status.values["missed_frames"] == "7" and status.values["gaps"] == "1"
        assert status.message == "all fingers streaming (7 dropped frames so far)"
        assert backend.clock.dropped == 7
    finally:
        port.close()
        hub.close()
