// STAG tactile glove readout: scans the 32x32 piezoresistive grid and streams protocol-v1 frames
// (docs/protocols.md, "STAG glove readout") at 250000 baud.
//
// Circuit (as in the STAG paper): each of the 32 row electrodes sits on an SPDT switch that ties
// it either to ground or to the excitation line; the 32 column electrodes go through a 32:1
// analog multiplexer into a voltage divider read by the 10-bit ADC. Selecting row r (excited, all
// other rows grounded, which suppresses crosstalk through neighbouring sensors) and column c
// reads the sensor at (r, c): its resistance falls with pressure, so the ADC value rises.
//
// Wiring for an Arduino Mega 2560 (5 V, 10-bit ADC):
//   row switches: 4 daisy-chained 74HC595 shift registers drive the 32 SPDT control inputs
//                 (e.g. ADG633/ADG733 IN pins); DATA pin 51 (MOSI), CLOCK pin 52 (SCK), LATCH pin 53
//                 bit r of the 32-bit word high = row r excited, low = row r grounded
//   column mux:   ADG732 (32:1): address A0..A4 on pins 22..26, /EN pin 27 (low = enabled),
//                 /CS and /WR tied low (transparent address latch)
//   ADC input:    mux output -> divider node -> analog pin A0
// Rate: 1024 conversions at ~112 us each plus 20 us settling take ~135 ms, i.e. ~7.3 frames/s.
// One 1289-byte frame takes 51.6 ms at 250000 baud; it is sent in pieces, whenever the serial
// transmit buffer has room, while the next frame is scanned, so sending costs no scan time.

#include <SPI.h>
#include "stag_frame.h"

static const uint8_t ROWS = 32;
static const uint8_t COLS = 32;
static const uint32_t BAUD = 250000;
static const uint8_t LATCH_PIN = 53;
static const uint8_t MUX_ADDRESS_PINS[5] = {22, 23, 24, 25, 26};
static const uint8_t MUX_ENABLE_PIN = 27;  // active low
static const uint8_t ADC_PIN = A0;
static const uint16_t SETTLE_US = 20;      // after switching a row or the mux address

static uint16_t readings[ROWS * COLS];
static uint8_t frame[STAG_FRAME_SIZE(ROWS, COLS)];
static uint16_t sequence = 0;
static size_t pending = 0;  // bytes of `frame` to send
static size_t sent = 0;     // bytes of `frame` already handed to Serial

// Hand the serial driver as much of the previous frame as fits without blocking.
static void drainSerial() {
  int room = Serial.availableForWrite();
  while (room > 0 && sent < pending) {
    size_t chunk = pending - sent;
    if (chunk > (size_t)room) chunk = (size_t)room;
    sent += Serial.write(frame + sent, chunk);
    room = Serial.availableForWrite();
  }
}

static void selectRow(uint8_t row) {
  uint32_t word = (uint32_t)1 << row;
  digitalWrite(LATCH_PIN, LOW);
  for (int8_t b = 3; b >= 0; --b) SPI.transfer((uint8_t)(word >> (8 * b)));  // last byte = rows 0..7
  digitalWrite(LATCH_PIN, HIGH);
}

static void selectColumn(uint8_t col) {
  for (uint8_t bit = 0; bit < 5; ++bit) digitalWrite(MUX_ADDRESS_PINS[bit], (col >> bit) & 1);
}

void setup() {
  Serial.begin(BAUD);
  SPI.begin();
  SPI.beginTransaction(SPISettings(4000000, MSBFIRST, SPI_MODE0));
  pinMode(LATCH_PIN, OUTPUT);
  for (uint8_t bit = 0; bit < 5; ++bit) pinMode(MUX_ADDRESS_PINS[bit], OUTPUT);
  pinMode(MUX_ENABLE_PIN, OUTPUT);
  digitalWrite(MUX_ENABLE_PIN, LOW);
  analogReference(DEFAULT);  // 5 V: 0..1023 = 0..5 V
}

void loop() {
  for (uint8_t r = 0; r < ROWS; ++r) {
    selectRow(r);
    delayMicroseconds(SETTLE_US);
    for (uint8_t c = 0; c < COLS; ++c) {
      selectColumn(c);
      delayMicroseconds(SETTLE_US);
      readings[(uint16_t)r * COLS + c] = (uint16_t)analogRead(ADC_PIN);
      drainSerial();
    }
  }
  if (sent < pending) Serial.write(frame + sent, pending - sent);  // rest of the previous frame
  pending = stag_encode_frame(readings, ROWS, COLS, sequence++, frame);
  sent = 0;
}
