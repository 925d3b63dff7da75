// PRISMA fingertip hub: Arduino Nano firmware.
//
// Reads the five optoelectronic fingertip sensors (one MAX11617 12-bit ADC each, I2C address 0x35,
// all behind a TCA9548A I2C multiplexer at 0x70) and streams them over serial in the framed
// binary protocol of docs/protocols.md ("Fingertip hub serial protocol"), which
// prisma_tactile_driver/protocol.py parses:
//
//   0xA5 0x5A | version 1 | sequence uint16 LE | finger mask | 14 bytes per finger | CRC16 LE
//
// Per finger: mux channel select (write 1 << channel to 0x70), MAX11617 setup byte 0x82
// (VDD reference, internal clock, unipolar, no reset) and configuration byte 0x11 (scan AIN0 up
// to CS = AIN8, single-ended), then an 18-byte read: 9 results, value = ((b0 & 0x0F) << 8) | b1.
// A finger whose ADC does not acknowledge is left out of the frame's finger mask, so the host
// sees it go stale while the others keep streaming.

#include <Wire.h>

// ---- configuration -------------------------------------------------------------------------
#ifndef HUB_BAUD
#define HUB_BAUD 1000000UL  // 1 Mbaud: a 78-byte five-finger frame takes 0.78 ms
#endif
#ifndef HUB_RATE_HZ
#define HUB_RATE_HZ 100     // frames per second (the paper's rate); the link allows ~1 kHz
#endif
#ifndef HUB_I2C_HZ
#define HUB_I2C_HZ 400000UL
#endif

static const uint8_t MUX_ADDRESS = 0x70;
static const uint8_t ADC_ADDRESS = 0x35;
static const uint8_t ADC_SETUP = 0x82;   // 1 000 0 0 1 0: setup, VDD ref, int clock, unipolar, no reset
static const uint8_t ADC_CONFIG = 0x11;  // 0 00 1000 1: config, scan AIN0..CS, CS = AIN8, single-ended
static const uint8_t N_FINGERS = 5;
static const uint8_t N_TAXELS = 9;
// mux channel of each finger, in protocol bit order (thumb, index, middle, ring, little)
static const uint8_t FINGER_CHANNEL[N_FINGERS] = {0, 1, 2, 3, 4};

static const uint8_t SYNC0 = 0xA5;
static const uint8_t SYNC1 = 0x5A;
static const uint8_t PROTOCOL_VERSION = 1;
static const uint8_t FINGER_PAYLOAD = 14;

static uint16_t sequence = 0;
static uint8_t frame[6 + N_FINGERS * FINGER_PAYLOAD + 2];

// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection (check "123456789" = 0x29B1)
static uint16_t crc16_ccitt(const uint8_t *data, uint16_t length) {
  uint16_t crc = 0xFFFF;
  while (length--) {
    crc ^= (uint16_t)(*data++) << 8;
    for (uint8_t bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
    }
  }
  return crc;
}

static bool select_channel(uint8_t channel) {
  Wire.beginTransmission(MUX_ADDRESS);
  Wire.write((uint8_t)(1 << channel));
  return Wire.endTransmission() == 0;
}

// Reads the 9 taxels of the ADC on the selected channel. false on any NACK or short read.
static bool read_taxels(uint16_t counts[N_TAXELS]) {
  Wire.beginTransmission(ADC_ADDRESS);
  Wire.write(ADC_SETUP);
  Wire.write(ADC_CONFIG);
  if (Wire.endTransmission() != 0) {
    return false;
  }
  const uint8_t n_bytes = 2 * N_TAXELS;
  if (Wire.requestFrom(ADC_ADDRESS, n_bytes) != n_bytes) {
    while (Wire.available()) Wire.read();
    return false;
  }
  for (uint8_t i = 0; i < N_TAXELS; ++i) {
    uint8_t b0 = Wire.read();
    uint8_t b1 = Wire.read();
    counts[i] = ((uint16_t)(b0 & 0x0F) << 8) | b1;
  }
  return true;
}

// 9 x 12-bit counts -> 14 bytes: pairs in 3 bytes, the ninth in 2 (see docs/protocols.md)
static void pack_counts(const uint16_t counts[N_TAXELS], uint8_t *out) {
  for (uint8_t pair = 0; pair < 4; ++pair) {
    uint16_t a = counts[2 * pair];
    uint16_t b = counts[2 * pair + 1];
    out[3 * pair + 0] = a & 0xFF;
    out[3 * pair + 1] = (uint8_t)((a >> 8) & 0x0F) | (uint8_t)((b & 0x0F) << 4);
    out[3 * pair + 2] = (uint8_t)(b >> 4);
  }
  out[12] = counts[8] & 0xFF;
  out[13] = (counts[8] >> 8) & 0x0F;
}

void setup() {
  Serial.begin(HUB_BAUD);
  Wire.begin();
  Wire.setClock(HUB_I2C_HZ);
#if defined(WIRE_HAS_TIMEOUT)
  Wire.setWireTimeout(3000 /* us */, true);  // a stuck bus must not stall the stream
#endif
}

void loop() {
  static uint32_t next_us = micros();
  const uint32_t period_us = 1000000UL / HUB_RATE_HZ;
  if ((int32_t)(micros() - next_us) < 0) {
    return;
  }
  next_us += period_us;

  uint8_t mask = 0;
  uint8_t length = 6;
  uint16_t counts[N_TAXELS];
  for (uint8_t finger = 0; finger < N_FINGERS; ++finger) {
    if (select_channel(FINGER_CHANNEL[finger]) && read_taxels(counts)) {
      mask |= (uint8_t)(1 << finger);
      pack_counts(counts, frame + length);
      length += FINGER_PAYLOAD;
    }
  }
  if (mask == 0) {
    return;  // no sensor answered: send nothing, the host reports every finger stale
  }
  frame[0] = SYNC0;
  frame[1] = SYNC1;
  frame[2] = PROTOCOL_VERSION;
  frame[3] = sequence & 0xFF;
  frame[4] = sequence >> 8;
  frame[5] = mask;
  uint16_t crc = crc16_ccitt(frame + 2, length - 2);
  frame[length++] = crc & 0xFF;
  frame[length++] = crc >> 8;
  Serial.write(frame, length);
  ++sequence;
}
