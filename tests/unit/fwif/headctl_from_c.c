/* Head-controller frames built and read the way board firmware would: in C99, from the
 * constants of headctl_protocol.h alone. The C++ tests compare them with the host codec. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "firmware-interface/headctl/headctl_protocol.h"

static void put_u16(uint8_t* at, uint16_t value) {
  at[0] = (uint8_t)(value & 0xFFu);
  at[1] = (uint8_t)(value >> 8);
}

static void put_u32(uint8_t* at, uint32_t value) {
  unsigned i;
  for (i = 0; i < 4u; ++i) at[i] = (uint8_t)((value >> (8u * i)) & 0xFFu);
}

static uint32_t get_u32(const uint8_t* at) {
  return (uint32_t)at[0] | ((uint32_t)at[1] << 8) | ((uint32_t)at[2] << 16) | ((uint32_t)at[3] << 24);
}

uint32_t headctl_c_check_value(void);
size_t headctl_c_build_frame(uint8_t* out, uint8_t flags, uint8_t type, uint8_t sequence, const uint8_t* payload,
                             uint16_t length);
size_t headctl_c_move_request(uint8_t* out, uint8_t sequence, uint32_t target_step, uint8_t direction,
                              uint32_t speed);
int headctl_c_read_turntable_status(const uint8_t* frame, size_t size, struct headctl_turntable_status* status);

uint32_t headctl_c_check_value(void) {
  static const uint8_t digits[9] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  return headctl_crc32(0, digits, sizeof digits);
}

size_t headctl_c_build_frame(uint8_t* out, uint8_t flags, uint8_t type, uint8_t sequence, const uint8_t* payload,
                             uint16_t length) {
  size_t size = HEADCTL_FRAME_HEADER_SIZE + length;
  out[HEADCTL_FRAME_OFF_SYNC0] = HEADCTL_SYNC0;
  out[HEADCTL_FRAME_OFF_SYNC1] = HEADCTL_SYNC1;
  out[HEADCTL_FRAME_OFF_VERSION] = HEADCTL_PROTOCOL_VERSION;
  out[HEADCTL_FRAME_OFF_FLAGS] = flags;
  out[HEADCTL_FRAME_OFF_TYPE] = type;
  out[HEADCTL_FRAME_OFF_SEQUENCE] = sequence;
  put_u16(out + HEADCTL_FRAME_OFF_LENGTH, length);
  if (length > 0u) memcpy(out + HEADCTL_FRAME_HEADER_SIZE, payload, length);
  put_u32(out + size, headctl_crc32(0, out + HEADCTL_FRAME_OFF_VERSION, size - HEADCTL_FRAME_OFF_VERSION));
  return size + HEADCTL_FRAME_CRC_SIZE;
}

size_t headctl_c_move_request(uint8_t* out, uint8_t sequence, uint32_t target_step, uint8_t direction,
                              uint32_t speed) {
  uint8_t payload[HEADCTL_TURNTABLE_MOVE_REQUEST_SIZE];
  memset(payload, 0, sizeof payload);
  put_u32(payload + HEADCTL_TURNTABLE_MOVE_OFF_TARGET_STEP, target_step);
  payload[HEADCTL_TURNTABLE_MOVE_OFF_DIRECTION] = direction;
  put_u32(payload + HEADCTL_TURNTABLE_MOVE_OFF_SPEED, speed);
  return headctl_c_build_frame(out, 0, HEADCTL_MSG_TURNTABLE_MOVE, sequence, payload, sizeof payload);
}

/* 0 on success; -1 bad frame, -2 not a TURNTABLE_STATUS reply, -3 wrong size. */
int headctl_c_read_turntable_status(const uint8_t* frame, size_t size, struct headctl_turntable_status* status) {
  const uint8_t* p = frame + HEADCTL_FRAME_HEADER_SIZE;
  size_t length;
  if (size < HEADCTL_FRAME_HEADER_SIZE + HEADCTL_FRAME_CRC_SIZE || frame[0] != HEADCTL_SYNC0 ||
      frame[1] != HEADCTL_SYNC1) {
    return -1;
  }
  length = (size_t)frame[HEADCTL_FRAME_OFF_LENGTH] | ((size_t)frame[HEADCTL_FRAME_OFF_LENGTH + 1u] << 8);
  if (size != HEADCTL_FRAME_HEADER_SIZE + length + HEADCTL_FRAME_CRC_SIZE ||
      headctl_crc32(0, frame + HEADCTL_FRAME_OFF_VERSION, HEADCTL_FRAME_HEADER_SIZE - HEADCTL_FRAME_OFF_VERSION + length) !=
          get_u32(frame + HEADCTL_FRAME_HEADER_SIZE + length)) {
    return -1;
  }
  if (frame[HEADCTL_FRAME_OFF_TYPE] != HEADCTL_MSG_TURNTABLE_STATUS || frame[HEADCTL_FRAME_OFF_FLAGS] != HEADCTL_FLAG_REPLY) {
    return -2;
  }
  if (length != HEADCTL_TURNTABLE_STATUS_REPLY_SIZE) return -3;
  status->state = p[HEADCTL_TURNTABLE_STATUS_OFF_STATE];
  status->homed = p[HEADCTL_TURNTABLE_STATUS_OFF_HOMED];
  status->fault = (uint16_t)(p[HEADCTL_TURNTABLE_STATUS_OFF_FAULT] | (p[HEADCTL_TURNTABLE_STATUS_OFF_FAULT + 1u] << 8));
  status->position_step = get_u32(p + HEADCTL_TURNTABLE_STATUS_OFF_POSITION_STEP);
  status->target_step = get_u32(p + HEADCTL_TURNTABLE_STATUS_OFF_TARGET_STEP);
  status->steps_per_revolution = get_u32(p + HEADCTL_TURNTABLE_STATUS_OFF_STEPS_PER_REV);
  status->speed_steps_per_s = get_u32(p + HEADCTL_TURNTABLE_STATUS_OFF_SPEED);
  return 0;
}
