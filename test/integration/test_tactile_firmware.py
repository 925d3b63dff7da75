"""The Arduino sketch, compiled on the host against stub Wire/Serial, emits frames the driver parses.

Skips when no C++ compiler is installed.
"""
import shutil
import subprocess

import numpy as np
import pytest

from prisma_tactile_driver.protocol import FrameParser
from prisma_testing.repo_paths import ROOT

SKETCH = ROOT / "firmware" / "prisma_fingertip_hub" / "prisma_fingertip_hub.ino"
CXX = shutil.which("g++") or shutil.which("clang++")

WIRE_STUB = r"""
#pragma once
#include <stdint.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <vector>
// Host stand-ins for the Arduino core: micros(), Serial and a Wire bus with a TCA9548A at 0x70 and
// MAX11617 ADCs at 0x35 on the channels listed in the ABSENT mask's complement.
static uint32_t fake_us = 0;
static uint32_t micros() { return fake_us; }
static int frame_index = 0;
static unsigned absent_channels = 0;
struct SerialStub {
  void begin(unsigned long) {}
  size_t write(const uint8_t *data, size_t n) { return fwrite(data, 1, n, stdout); }
} Serial;
static uint16_t adc_value(int channel, int taxel) { return (channel * 523 + taxel * 97 + frame_index * 13) & 0x0FFF; }
struct WireStub {
  uint8_t address = 0, mux = 0, setup = 0, config = 0;
  std::vector<uint8_t> tx, rx;
  size_t rx_pos = 0;
  void begin() {}
  void setClock(unsigned long) {}
  void beginTransmission(uint8_t a) { address = a; tx.clear(); }
  size_t write(uint8_t b) { tx.push_back(b); return 1; }
  int selected() {
    for (int c = 0; c < 8; ++c) if (mux == (1u << c) && !(absent_channels >> c & 1)) return c;
    return -1;
  }
  uint8_t endTransmission() {
    if (address == 0x70) { if (!tx.empty()) mux = tx.back(); return 0; }
    if (address == 0x35 && selected() >= 0) {
      for (uint8_t b : tx) { if (b & 0x80) setup = b; else config = b; }
      return 0;
    }
    return 2;  // NACK on address
  }
  uint8_t requestFrom(uint8_t a, uint8_t n) {
    rx.clear(); rx_pos = 0;
    int ch = selected();
    if (a != 0x35 || ch < 0 || setup != 0x82 || config != 0x11) return 0;
    int last = (config >> 1) & 0x0F;
    for (int i = 0; rx.size() < n; i = (i + 1) % (last + 1)) {
      uint16_t v = adc_value(ch, i);
      rx.push_back(0xF0 | (v >> 8));
      rx.push_back(v & 0xFF);
    }
    return n;
  }
  int available() { return (int)(rx.size() - rx_pos); }
  int read() { return rx[rx_pos++]; }
} Wire;
"""

MAIN = r"""
#include "prisma_fingertip_hub.ino"
int main(int argc, char **argv) {
  int frames = atoi(argv[1]);
  absent_channels = (unsigned)atoi(argv[2]);
  setup();
  for (frame_index = 0; frame_index < frames; ++frame_index) {
    fake_us += 1000000UL / HUB_RATE_HZ;
    loop();
  }
  return 0;
}
"""


@pytest.fixture(scope="module")
def hub_binary(tmp_path_factory):
    if CXX is None:
        pytest.skip("no C++ compiler to build the sketch on the host")
    build = tmp_path_factory.mktemp("firmware")
    (build / "Wire.h").write_text(WIRE_STUB)
    shutil.copy(SKETCH, build / SKETCH.name)
    (build / "main.cpp").write_text(MAIN)
    binary = build / "hub"
    subprocess.run([CXX, "-std=c++17", "-Wall", "-Werror", "-I", str(build), str(build / "main.cpp"),
                    "-o", str(binary)], check=True, capture_output=True, text=True)
    return binary


def expected_counts(channel: int, frame: int) -> np.ndarray:
    return (channel * 523 + np.arange(9) * 97 + frame * 13) & 0x0FFF


def test_sketch_streams_the_documented_protocol(hub_binary):
    out = subprocess.run([str(hub_binary), "50", "0"], check=True, capture_output=True).stdout
    parser = FrameParser()
    frames = parser.feed(out)
    assert len(frames) == 50 and len(out) == 50 * 78
    assert parser.stats.garbage_bytes == 0 and parser.stats.crc_errors == 0
    assert [f.sequence for f in frames] == list(range(50))
    for i, frame in enumerate(frames):
        assert frame.fingers == ("thumb", "index", "middle", "ring", "little")
        for channel, counts in enumerate(frame.counts):
            np.testing.assert_array_equal(counts, expected_counts(channel, i))


def test_sketch_leaves_a_nacking_finger_out_of_the_mask(hub_binary):
    out = subprocess.run([str(hub_binary), "3", str(1 << 2)], check=True, capture_output=True).stdout
    frames = FrameParser().feed(out)
    assert len(frames) == 3
    assert all(f.fingers == ("thumb", "index", "ring", "little") for f in frames)
    np.testing.assert_array_equal(frames[1].by_finger()["ring"], expected_counts(3, 1))
