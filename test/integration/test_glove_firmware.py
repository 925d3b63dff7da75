"""The readout firmware's frame encoder (firmware/stag_readout/stag_frame.h) compiled on the host
must produce exactly the bytes the Python parser expects."""
import re
import shutil
import subprocess

import numpy as np
import pytest

from prisma_testing.repo_paths import ROOT
from stag_glove.protocol import SYNC, VERSION, GloveStreamParser, encode_frame

FIRMWARE = ROOT / "firmware" / "stag_readout"

HARNESS = r"""
#include <stdio.h>
#include "stag_frame.h"
int main(void) {
  static uint16_t readings[32 * 32];
  static uint8_t out[STAG_FRAME_SIZE(32, 32)];
  unsigned v;
  for (int i = 0; i < 32 * 32; ++i) { if (scanf("%u", &v) != 1) return 2; readings[i] = (uint16_t)v; }
  size_t n = stag_encode_frame(readings, 32, 32, 0xBEEF, out);
  fwrite(out, 1, n, stdout);
  return 0;
}
"""


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")
def test_firmware_encoder_matches_python(tmp_path):
    source = tmp_path / "harness.c"
    source.write_text(HARNESS)
    exe = tmp_path / "harness"
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Werror", "-I", str(FIRMWARE), str(source), "-o", str(exe)],
                   check=True)
    raw = np.random.default_rng(7).integers(0, 1024, (32, 32)).astype(np.uint16)
    raw[0, :4] = [0, 1023, 512, 1]
    out = subprocess.run([str(exe)], input=" ".join(map(str, raw.ravel())).encode(), capture_output=True, check=True)
    assert out.stdout == encode_frame(raw, 0xBEEF)
    frames = GloveStreamParser().feed(out.stdout)
    np.testing.assert_array_equal(frames[0].raw, raw)


def test_sketch_constants_match_the_protocol():
    header = (FIRMWARE / "stag_frame.h").read_text()
    sketch = (FIRMWARE / "stag_readout.ino").read_text()
    assert f"#define STAG_SYNC0 0x{SYNC[0]:02X}" in header
    assert f"#define STAG_SYNC1 0x{SYNC[1]:02X}" in header
    assert f"#define STAG_VERSION {VERSION}" in header
    assert re.search(r"BAUD = 250000;", sketch)
    assert "ROWS = 32" in sketch and "COLS = 32" in sketch
