"""Direct I2C backend against an emulated TCA9548A + five MAX11617, through real smbus2 calls."""
import errno

import numpy as np
import pytest
from smbus2 import i2c_msg

from prisma_common.diagnostics import ERROR, OK, STALE
from prisma_common.hand import FINGERS
from prisma_tactile_driver.i2c_backend import BadReadError, I2CHubBackend, check_channel_map, decode_max11617
from prisma_tactile_driver.i2c_emulator import EmulatedSMBus, five_finger_bus
from prisma_tactile_driver.tactile_driver_core import TactileHub

CHANNELS = {"thumb": 0, "index": 1, "middle": 2, "ring": 3, "little": 4}
RNG = np.random.default_rng(3)
VALUES = {ch: RNG.integers(0, 4096, 12) for ch in range(5)}


@pytest.fixture
def bus():
    return five_finger_bus(VALUES)


MS = 1_000_000


def test_decode_masks_the_high_nibble():
    assert decode_max11617(bytes([0xF1, 0x23] * 9)).tolist() == [0x123] * 9


def test_decode_rejects_a_high_nibble_other_than_1111():
    with pytest.raises(BadReadError, match=r"AIN0 0x0000, AIN1 0x0000, AIN2 0x0000 and 6 more$"):
        decode_max11617(bytes(18))
    data = bytearray([0xF1, 0x23] * 9)
    data[8] = 0x71  # AIN4's first byte with one high bit lost
    with pytest.raises(BadReadError, match=r"high nibble not 1111 in AIN4 0x7123$"):
        decode_max11617(bytes(data))


def test_emulated_bus_behaves_like_the_datasheets(bus):
    smbus = EmulatedSMBus(bus)
    # nothing selected: the ADC address NACKs like i2c-dev does (OSError EREMOTEIO)
    with pytest.raises(OSError) as info:
        smbus.i2c_rdwr(i2c_msg.write(0x35, [0x82, 0x11]))
    assert info.value.errno == errno.EREMOTEIO
    smbus.i2c_rdwr(i2c_msg.write(0x70, [1 << 3]))
    readback = i2c_msg.read(0x70, 1)
    smbus.i2c_rdwr(readback)
    assert bytes(readback) == bytes([0x08])
    config, result = i2c_msg.write(0x35, [0x82, 0x11]), i2c_msg.read(0x35, 18)
    smbus.i2c_rdwr(config, result)
    raw = bytes(result)
    assert all(b >> 4 == 0xF for b in raw[::2])
    assert bus.adcs[3].setup == 0x82 and bus.adcs[3].config == 0x11
    np.testing.assert_array_equal(decode_max11617(raw), VALUES[3][:9])
    with pytest.raises(OSError):  # an address nobody has
        smbus.i2c_rdwr(i2c_msg.write(0x48, [0]))


def test_backend_returns_exactly_the_emulated_adc_values(bus):
    backend = I2CHubBackend(EmulatedSMBus(bus), CHANNELS)
    [reading] = backend.read(0)
    assert set(reading.counts) == set(FINGERS)
    for finger, ch in CHANNELS.items():
        np.testing.assert_array_equal(reading.counts[finger], VALUES[ch][:9])
    # a remapped hub: fingers on other mux channels
    remapped = I2CHubBackend(EmulatedSMBus(bus), {"index": 4, "thumb": 2})
    [reading] = remapped.read(0)
    np.testing.assert_array_equal(reading.counts["index"], VALUES[4][:9])
    np.testing.assert_array_equal(reading.counts["thumb"], VALUES[2][:9])


def test_transient_nack_is_retried(bus):
    bus.adcs[1].nack_next = 2
    backend = I2CHubBackend(EmulatedSMBus(bus), CHANNELS, retries=2)
    [reading] = backend.read(0)
    np.testing.assert_array_equal(reading.counts["index"], VALUES[1][:9])
    assert backend.stats["index"].errors == 2 and backend.stats["index"].failed_scans == 0


def test_nacking_finger_goes_stale_while_the_others_keep_publishing(bus):
    bus.adcs[2].failing = True  # the middle finger's sensor is unplugged
    backend = I2CHubBackend(EmulatedSMBus(bus), CHANNELS, retries=2)
    hub = TactileHub(backend, FINGERS, stale_timeout_ns=100_000_000)
    frames = []
    for step in range(30):  # 300 ms at 100 Hz
        frames += hub.poll(step * 10_000_000)
    assert {f.finger for f in frames} == {"thumb", "index", "ring", "little"}
    assert len(frames) == 4 * 30
    for f in frames[:4]:
        np.testing.assert_allclose(f.voltages, VALUES[CHANNELS[f.finger]][:9] * 3.3 / 4096, rtol=1e-6)
    assert backend.stats["middle"].errors == 3 * 30  # bounded: 1 try + 2 retries per scan
    assert backend.stats["middle"].consecutive_failures == 30
    statuses = {s.name: s for s in hub.diagnostics(300_000_000)}
    assert statuses["tactile_driver: middle"].level == STALE
    assert statuses["tactile_driver: thumb"].level == OK
    assert "middle" in statuses["tactile_driver: hub"].message
    assert statuses["tactile_driver: hub"].values["middle_errors"] == "90"
    # plugged back in: it recovers on the next scan
    bus.adcs[2].failing = False
    frames = hub.poll(310_000_000)
    assert {f.finger for f in frames} == set(FINGERS)
    assert hub.stale_fingers(310_000_000) == []


def test_channel_map_is_validated():
    with pytest.raises(ValueError, match="duplicate mux channel 1"):
        check_channel_map({"thumb": 1, "index": 1})
    with pytest.raises(ValueError, match="pinky"):
        check_channel_map({"pinky": 0})
    with pytest.raises(ValueError, match="0..7"):
        check_channel_map({"thumb": 8})


def test_glitched_all_zero_read_is_a_bus_error_not_zero_counts(bus):
    bus.adcs[1].glitch_next = 1  # one read of the index finger's ADC returns all zeros
    backend = I2CHubBackend(EmulatedSMBus(bus), CHANNELS, retries=2)
    hub = TactileHub(backend, FINGERS)
    frames = {f.finger: f for f in hub.poll(0)}
    np.testing.assert_array_equal(frames["index"].counts, VALUES[1][:9])  # the retry read it right
    stats = backend.stats["index"]
    assert stats.errors == 1 and stats.bad_reads == 1 and stats.failed_scans == 0
    assert hub.take_errors() == []  # recovered within the scan: counted, not reported
    # a glitch outlasting the retries: the finger is left out of that scan
    bus.adcs[1].glitch_next = 3
    frames = hub.poll(10 * MS)
    assert sorted(f.finger for f in frames) == sorted(set(FINGERS) - {"index"})
    counters = backend.counters()
    assert counters["index_bad_reads"] == 4 and counters["index_errors"] == 4
    assert counters["index_failed_scans"] == 1 and counters["thumb_bad_reads"] == 0
    reason = ("index: mux channel 1: bad MAX11617 read: high nibble not 1111 in "
              "AIN0 0x0000, AIN1 0x0000, AIN2 0x0000 and 6 more")
    assert hub.take_errors() == [reason]
    status = hub.diagnostics(10 * MS)[0]
    assert status.message == f"all fingers streaming; {reason}"
    assert status.values["index_last_error"] == reason.removeprefix("index: ")
    assert {f.finger for f in hub.poll(20 * MS)} == set(FINGERS)  # the next scan reads it again
    assert hub.link_status().error == "" and hub.take_errors() == []


def test_a_bus_that_cannot_be_opened_says_why_and_is_retried():
    attempts = []

    def missing_bus(number):
        attempts.append(number)
        raise FileNotFoundError(2, "No such file or directory")

    backend = I2CHubBackend(7, CHANNELS, bus_factory=missing_bus)
    hub = TactileHub(backend, FINGERS)
    assert attempts == [7]  # at construction
    for t_ms in range(0, 2500, 10):
        assert hub.poll(t_ms * MS) == []
    assert attempts == [7] * 4  # then at the first read and once a second
    reason = "cannot open I2C bus /dev/i2c-7: [Errno 2] No such file or directory"
    assert hub.take_errors() == [reason]
    status = hub.diagnostics(2500 * MS)[0]
    assert status.level == ERROR and status.message == f"stale: {', '.join(FINGERS)}; {reason}"
    assert status.values["bus"] == "/dev/i2c-7" and status.values["open_failures"] == "4"
    assert status.values["scans"] == "0"
    emulated = five_finger_bus(VALUES)
    backend._factory = lambda number: EmulatedSMBus(emulated)  # the bus appears
    assert {f.finger for f in hub.poll(3000 * MS)} == set(FINGERS)
    assert hub.take_errors() == [] and hub.diagnostics(3000 * MS)[0].level == OK


def test_a_flapping_finger_is_reported_once_until_it_has_worked_for_a_second(bus):
    backend = I2CHubBackend(EmulatedSMBus(bus), CHANNELS, retries=0)
    hub = TactileHub(backend, FINGERS)
    reports = []
    for scan in range(200):  # 2 s at 100 Hz, the ring finger NACKing every other scan
        bus.adcs[3].nack_next = scan % 2
        hub.poll(scan * 10 * MS)
        reports += hub.take_errors()
    reason = "ring: mux channel 3: [Errno 121] Remote I/O error (no ACK from 0x35)"
    assert reports == [reason] and backend.stats["ring"].failed_scans == 100
    for scan in range(200, 300):  # working for 0.99 s: still the same story
        hub.poll(scan * 10 * MS)
    bus.adcs[3].nack_next = 1
    hub.poll(300 * 10 * MS)
    assert hub.take_errors() == []
    for scan in range(301, 402):  # working for a second
        hub.poll(scan * 10 * MS)
    bus.adcs[3].nack_next = 1
    hub.poll(402 * 10 * MS)
    assert hub.take_errors() == [reason]  # news again
