// STAG readout frame encoding, protocol version 1 (docs/protocols.md, "STAG glove readout").
// Plain C99 with no Arduino dependency, so the host test suite compiles it with gcc and checks
// its bytes against the Python parser (test/test_glove_firmware.py).
//
//   sync 0xA5 0x5A | version | rows | cols | sequence (u16 LE) | readings, 10 bit, 4 per 5 bytes |
//   CRC-16/CCITT-FALSE of version..readings (u16 LE)
#ifndef STAG_FRAME_H
#define STAG_FRAME_H

#include <stdint.h>
#include <stddef.h>

#define STAG_SYNC0 0xA5
#define STAG_SYNC1 0x5A
#define STAG_VERSION 1
#define STAG_HEADER_SIZE 7
#define STAG_CRC_SIZE 2
#define STAG_FRAME_SIZE(rows, cols) (STAG_HEADER_SIZE + (rows) * (cols) * 10 / 8 + STAG_CRC_SIZE)

// CRC-16/CCITT-FALSE: polynomial 0x1021, initial value 0xFFFF, no reflection, no final XOR.
static inline uint16_t stag_crc16_update(uint16_t crc, uint8_t byte) {
  crc ^= (uint16_t)byte << 8;
  for (uint8_t bit = 0; bit < 8; ++bit) {
    crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
  }
  return crc;
}

// Pack four 10-bit readings into five bytes: the 40-bit little-endian word holds reading k in
// bits 10k..10k+9.
static inline void stag_pack4(const uint16_t v[4], uint8_t out[5]) {
  out[0] = (uint8_t)(v[0] & 0xFF);
  out[1] = (uint8_t)(((v[0] >> 8) & 0x03) | ((v[1] & 0x3F) << 2));
  out[2] = (uint8_t)(((v[1] >> 6) & 0x0F) | ((v[2] & 0x0F) << 4));
  out[3] = (uint8_t)(((v[2] >> 4) & 0x3F) | ((v[3] & 0x03) << 6));
  out[4] = (uint8_t)((v[3] >> 2) & 0xFF);
}

// Encode a whole frame (rows*cols readings, row-major, rows*cols divisible by 4) into `out`,
// which must hold STAG_FRAME_SIZE(rows, cols) bytes. Returns the number of bytes written.
static inline size_t stag_encode_frame(const uint16_t *readings, uint8_t rows, uint8_t cols,
                                       uint16_t sequence, uint8_t *out) {
  size_t n = 0;
  out[n++] = STAG_SYNC0;
  out[n++] = STAG_SYNC1;
  out[n++] = STAG_VERSION;
  out[n++] = rows;
  out[n++] = cols;
  out[n++] = (uint8_t)(sequence & 0xFF);
  out[n++] = (uint8_t)(sequence >> 8);
  const size_t count = (size_t)rows * cols;
  for (size_t i = 0; i + 3 < count; i += 4) {
    stag_pack4(&readings[i], &out[n]);
    n += 5;
  }
  uint16_t crc = 0xFFFF;
  for (size_t i = 2; i < n; ++i) crc = stag_crc16_update(crc, out[i]);
  out[n++] = (uint8_t)(crc & 0xFF);
  out[n++] = (uint8_t)(crc >> 8);
  return n;
}

#endif  // STAG_FRAME_H
