/* The slscan head-controller protocol, version 1: the constants, message layouts and CRC
 * that the board firmware and the host share. PROTOCOL.md beside this file is the
 * specification; this header is its machine-readable part, plain C99 (it compiles alone
 * with -std=c99 -pedantic-errors, and as C++) so OEM firmware can include it as is.
 *
 * Everything on the wire is little-endian. Payload layouts are given as byte offsets
 * (HEADCTL_<MESSAGE>_OFF_<FIELD>) and total sizes (HEADCTL_<MESSAGE>_SIZE) rather than as
 * packed structs, because C99 has no portable way to pack a struct. The structs below hold
 * decoded values for firmware that wants them; they are not wire images. */
#ifndef SLS_HEADCTL_PROTOCOL_H
#define SLS_HEADCTL_PROTOCOL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- USB ------------------------------------------------------------------------------ */
/* Development IDs: 0x1209 is the pid.codes open-hardware vendor ID; product 0x5CA1 is NOT yet
 * allocated there and must be registered (or replaced by the OEM's own IDs, which the host
 * driver accepts) before a board ships. */
#define HEADCTL_USB_VENDOR_ID 0x1209u
#define HEADCTL_USB_PRODUCT_ID 0x5CA1u
#define HEADCTL_USB_INTERFACE_CLASS 0xFFu /* vendor specific */
#define HEADCTL_USB_INTERFACE_NUMBER 0u
#define HEADCTL_USB_ENDPOINT_OUT 0x01u /* bulk, host to board */
#define HEADCTL_USB_ENDPOINT_IN 0x81u  /* bulk, board to host */

/* ---- framing --------------------------------------------------------------------------- */
#define HEADCTL_PROTOCOL_VERSION 1u
#define HEADCTL_SYNC0 0xA5u
#define HEADCTL_SYNC1 0x5Au

/* Byte offsets in a frame. */
#define HEADCTL_FRAME_OFF_SYNC0 0u
#define HEADCTL_FRAME_OFF_SYNC1 1u
#define HEADCTL_FRAME_OFF_VERSION 2u
#define HEADCTL_FRAME_OFF_FLAGS 3u
#define HEADCTL_FRAME_OFF_TYPE 4u
#define HEADCTL_FRAME_OFF_SEQUENCE 5u
#define HEADCTL_FRAME_OFF_LENGTH 6u /* uint16: payload bytes */
#define HEADCTL_FRAME_HEADER_SIZE 8u
#define HEADCTL_FRAME_CRC_SIZE 4u /* CRC-32 of bytes [VERSION, end of payload) */
#define HEADCTL_MAX_PAYLOAD 240u
#define HEADCTL_MAX_FRAME_SIZE (HEADCTL_FRAME_HEADER_SIZE + HEADCTL_MAX_PAYLOAD + HEADCTL_FRAME_CRC_SIZE)

/* Flags byte. Bits 2..7 are reserved and must be 0. */
#define HEADCTL_FLAG_REPLY 0x01u /* set in every board-to-host frame */
#define HEADCTL_FLAG_ERROR 0x02u /* a reply whose payload is an error (HEADCTL_ERROR_*) */
#define HEADCTL_FLAGS_RESERVED 0xFCu

/* ---- timing (milliseconds) ------------------------------------------------------------- */
#define HEADCTL_REPLY_DEADLINE_MS 20u      /* the board replies to every request within this */
#define HEADCTL_HOST_ATTEMPT_TIMEOUT_MS 100u /* the host's default wait for one attempt */
#define HEADCTL_HOST_MAX_ATTEMPTS 3u       /* first try plus two retries, same sequence number */

/* ---- message types (the request and its reply carry the same type) -------------------- */
enum headctl_message_type {
  HEADCTL_MSG_IDENTIFY = 0x01,
  HEADCTL_MSG_TRIGGER_CONFIGURE = 0x10,
  HEADCTL_MSG_TRIGGER_ARM = 0x11,
  HEADCTL_MSG_TRIGGER_FIRE = 0x12,
  HEADCTL_MSG_TRIGGER_STATUS = 0x13,
  HEADCTL_MSG_TRIGGER_DISARM = 0x14,
  HEADCTL_MSG_TURNTABLE_HOME = 0x20,
  HEADCTL_MSG_TURNTABLE_MOVE = 0x21,
  HEADCTL_MSG_TURNTABLE_STOP = 0x22,
  HEADCTL_MSG_TURNTABLE_STATUS = 0x23,
  HEADCTL_MSG_TURNTABLE_POSITION = 0x24,
  HEADCTL_MSG_TEMPERATURES = 0x30,
  HEADCTL_MSG_ERROR_LOG = 0x40,
  HEADCTL_MSG_ERROR_CLEAR = 0x41
};

/* ---- error codes (the first field of an error reply) ---------------------------------- */
enum headctl_error {
  HEADCTL_ERROR_BAD_FRAME = 0x0001,           /* sync, length, reserved flags or CRC wrong */
  HEADCTL_ERROR_UNSUPPORTED_VERSION = 0x0002, /* detail: the board's protocol version */
  HEADCTL_ERROR_UNKNOWN_MESSAGE = 0x0003,
  HEADCTL_ERROR_BAD_PAYLOAD = 0x0004,  /* wrong size, reserved byte not 0, enum out of range */
  HEADCTL_ERROR_OUT_OF_RANGE = 0x0005, /* detail: the limit that was exceeded */
  HEADCTL_ERROR_BUSY = 0x0006,         /* the turntable is moving or homing */
  HEADCTL_ERROR_NOT_HOMED = 0x0007,
  HEADCTL_ERROR_INVALID_STATE = 0x0008, /* e.g. FIRE with no sequence armed for the host */
  HEADCTL_ERROR_HARDWARE_FAULT = 0x0009 /* detail: the headctl_fault latched */
};

/* Latched turntable faults (TURNTABLE_STATUS.fault); HOME or ERROR_CLEAR clears them. */
enum headctl_fault {
  HEADCTL_FAULT_NONE = 0,
  HEADCTL_FAULT_MOTOR_STALL = 1,
  HEADCTL_FAULT_HOME_NOT_FOUND = 2,
  HEADCTL_FAULT_OVER_TEMPERATURE = 3,
  HEADCTL_FAULT_DRIVER = 4
};

enum headctl_turntable_state {
  HEADCTL_TURNTABLE_IDLE = 0,
  HEADCTL_TURNTABLE_HOMING = 1,
  HEADCTL_TURNTABLE_MOVING = 2,
  HEADCTL_TURNTABLE_FAULT = 3
};

enum headctl_direction { HEADCTL_DIRECTION_SHORTEST = 0, HEADCTL_DIRECTION_POSITIVE = 1, HEADCTL_DIRECTION_NEGATIVE = 2 };
enum headctl_polarity { HEADCTL_ACTIVE_HIGH = 0, HEADCTL_ACTIVE_LOW = 1 };
enum headctl_trigger_source { HEADCTL_TRIGGER_SOURCE_HOST = 0, HEADCTL_TRIGGER_SOURCE_TIMER = 1 };

/* IDENTIFY capabilities bits. */
#define HEADCTL_CAP_TRIGGERS 0x00000001u
#define HEADCTL_CAP_TURNTABLE 0x00000002u
#define HEADCTL_CAP_TEMPERATURES 0x00000004u

#define HEADCTL_MAX_TRIGGER_OUTPUTS 8u
#define HEADCTL_MAX_TEMPERATURE_SENSORS 8u
#define HEADCTL_MAX_ERROR_LOG_ENTRIES 8u
#define HEADCTL_MAX_ERROR_TEXT 64u
#define HEADCTL_SERIAL_SIZE 16u
#define HEADCTL_MODEL_SIZE 24u

/* ---- payload layouts (requests with no field listed have an empty payload) ------------ */
/* IDENTIFY reply */
#define HEADCTL_IDENTIFY_OFF_PROTOCOL_VERSION 0u /* uint8 */
#define HEADCTL_IDENTIFY_OFF_FIRMWARE_MAJOR 1u   /* uint8 */
#define HEADCTL_IDENTIFY_OFF_FIRMWARE_MINOR 2u   /* uint8 */
#define HEADCTL_IDENTIFY_OFF_FIRMWARE_PATCH 3u   /* uint8 */
#define HEADCTL_IDENTIFY_OFF_HARDWARE_REVISION 4u /* uint8 */
#define HEADCTL_IDENTIFY_OFF_TRIGGER_OUTPUTS 5u  /* uint8, <= HEADCTL_MAX_TRIGGER_OUTPUTS */
#define HEADCTL_IDENTIFY_OFF_TEMPERATURE_SENSORS 6u /* uint8, <= HEADCTL_MAX_TEMPERATURE_SENSORS */
#define HEADCTL_IDENTIFY_OFF_RESERVED 7u         /* uint8, 0 */
#define HEADCTL_IDENTIFY_OFF_CAPABILITIES 8u     /* uint32, HEADCTL_CAP_* */
#define HEADCTL_IDENTIFY_OFF_STEPS_PER_REV 12u   /* uint32, 0 without a turntable */
#define HEADCTL_IDENTIFY_OFF_SERIAL 16u          /* char[16], printable ASCII, NUL padded */
#define HEADCTL_IDENTIFY_OFF_MODEL 32u           /* char[24], printable ASCII, NUL padded */
#define HEADCTL_IDENTIFY_REPLY_SIZE 56u

/* TRIGGER_CONFIGURE request */
#define HEADCTL_TRIGGER_CONFIGURE_OFF_OUTPUT 0u      /* uint8, < trigger outputs */
#define HEADCTL_TRIGGER_CONFIGURE_OFF_ENABLED 1u     /* uint8, 0 or 1 */
#define HEADCTL_TRIGGER_CONFIGURE_OFF_POLARITY 2u    /* uint8, headctl_polarity */
#define HEADCTL_TRIGGER_CONFIGURE_OFF_RESERVED 3u    /* uint8, 0 */
#define HEADCTL_TRIGGER_CONFIGURE_OFF_PULSE_WIDTH_US 4u /* uint32, 1 .. 1000000 */
#define HEADCTL_TRIGGER_CONFIGURE_OFF_DELAY_US 8u    /* uint32, <= 1000000 */
#define HEADCTL_TRIGGER_CONFIGURE_REQUEST_SIZE 12u

/* TRIGGER_ARM request */
#define HEADCTL_TRIGGER_ARM_OFF_OUTPUT_MASK 0u /* uint8, bit n = output n; not 0 */
#define HEADCTL_TRIGGER_ARM_OFF_SOURCE 1u      /* uint8, headctl_trigger_source */
#define HEADCTL_TRIGGER_ARM_OFF_COUNT 2u       /* uint16, pulses in the sequence, >= 1 */
#define HEADCTL_TRIGGER_ARM_OFF_PERIOD_US 4u   /* uint32, timer source: pulse period; host: 0 */
#define HEADCTL_TRIGGER_ARM_REQUEST_SIZE 8u

/* TRIGGER_FIRE reply */
#define HEADCTL_TRIGGER_FIRE_OFF_PULSE_INDEX 0u  /* uint16, 0-based index in the sequence */
#define HEADCTL_TRIGGER_FIRE_OFF_REMAINING 2u    /* uint16, pulses left; 0 = disarmed now */
#define HEADCTL_TRIGGER_FIRE_OFF_RESERVED 4u     /* uint32, 0 */
#define HEADCTL_TRIGGER_FIRE_OFF_TIMESTAMP_US 8u /* uint64, board clock at the pulse edge */
#define HEADCTL_TRIGGER_FIRE_REPLY_SIZE 16u

/* TRIGGER_STATUS reply */
#define HEADCTL_TRIGGER_STATUS_OFF_ARMED 0u        /* uint8, 0 or 1 */
#define HEADCTL_TRIGGER_STATUS_OFF_OUTPUT_MASK 1u  /* uint8 */
#define HEADCTL_TRIGGER_STATUS_OFF_FIRED 2u        /* uint16, pulses of this sequence fired */
#define HEADCTL_TRIGGER_STATUS_OFF_REMAINING 4u    /* uint16 */
#define HEADCTL_TRIGGER_STATUS_OFF_RESERVED 6u     /* uint16, 0 */
#define HEADCTL_TRIGGER_STATUS_OFF_TOTAL_PULSES 8u /* uint32, since power-on, wraps */
#define HEADCTL_TRIGGER_STATUS_REPLY_SIZE 12u

/* TURNTABLE_MOVE request */
#define HEADCTL_TURNTABLE_MOVE_OFF_TARGET_STEP 0u /* uint32, < steps per revolution */
#define HEADCTL_TURNTABLE_MOVE_OFF_DIRECTION 4u   /* uint8, headctl_direction */
#define HEADCTL_TURNTABLE_MOVE_OFF_RESERVED 5u    /* uint8[3], 0 */
#define HEADCTL_TURNTABLE_MOVE_OFF_SPEED 8u       /* uint32, steps/s; 0 = the board's default */
#define HEADCTL_TURNTABLE_MOVE_REQUEST_SIZE 12u

/* TURNTABLE_STATUS reply */
#define HEADCTL_TURNTABLE_STATUS_OFF_STATE 0u         /* uint8, headctl_turntable_state */
#define HEADCTL_TURNTABLE_STATUS_OFF_HOMED 1u         /* uint8, 0 or 1 */
#define HEADCTL_TURNTABLE_STATUS_OFF_FAULT 2u         /* uint16, headctl_fault */
#define HEADCTL_TURNTABLE_STATUS_OFF_POSITION_STEP 4u /* uint32, < steps per revolution */
#define HEADCTL_TURNTABLE_STATUS_OFF_TARGET_STEP 8u   /* uint32 */
#define HEADCTL_TURNTABLE_STATUS_OFF_STEPS_PER_REV 12u /* uint32 */
#define HEADCTL_TURNTABLE_STATUS_OFF_SPEED 16u        /* uint32, steps/s of the current move */
#define HEADCTL_TURNTABLE_STATUS_REPLY_SIZE 20u

/* TURNTABLE_POSITION reply */
#define HEADCTL_TURNTABLE_POSITION_OFF_POSITION_STEP 0u  /* uint32 */
#define HEADCTL_TURNTABLE_POSITION_OFF_STEPS_PER_REV 4u  /* uint32 */
#define HEADCTL_TURNTABLE_POSITION_REPLY_SIZE 8u

/* TEMPERATURES reply: a count, then count entries */
#define HEADCTL_TEMPERATURES_OFF_COUNT 0u /* uint8, <= HEADCTL_MAX_TEMPERATURE_SENSORS */
#define HEADCTL_TEMPERATURES_OFF_ENTRIES 1u
#define HEADCTL_TEMPERATURE_ENTRY_OFF_SENSOR 0u        /* uint8 */
#define HEADCTL_TEMPERATURE_ENTRY_OFF_RESERVED 1u      /* uint8, 0 */
#define HEADCTL_TEMPERATURE_ENTRY_OFF_CENTI_CELSIUS 2u /* int16, 0.01 degC */
#define HEADCTL_TEMPERATURE_ENTRY_SIZE 4u

/* ERROR_LOG reply: a count, then count entries, oldest first */
#define HEADCTL_ERROR_LOG_OFF_COUNT 0u /* uint8, <= HEADCTL_MAX_ERROR_LOG_ENTRIES */
#define HEADCTL_ERROR_LOG_OFF_ENTRIES 1u
#define HEADCTL_ERROR_LOG_ENTRY_OFF_CODE 0u         /* uint16, headctl_error */
#define HEADCTL_ERROR_LOG_ENTRY_OFF_TYPE 2u         /* uint8, the message type refused */
#define HEADCTL_ERROR_LOG_ENTRY_OFF_SEQUENCE 3u     /* uint8 */
#define HEADCTL_ERROR_LOG_ENTRY_OFF_DETAIL 4u       /* uint32 */
#define HEADCTL_ERROR_LOG_ENTRY_OFF_TIMESTAMP_MS 8u /* uint32, board clock */
#define HEADCTL_ERROR_LOG_ENTRY_SIZE 12u

/* Error reply (HEADCTL_FLAG_ERROR set), to any request */
#define HEADCTL_ERROR_REPLY_OFF_CODE 0u        /* uint16, headctl_error */
#define HEADCTL_ERROR_REPLY_OFF_DETAIL 2u      /* uint32 */
#define HEADCTL_ERROR_REPLY_OFF_TEXT_LENGTH 6u /* uint8, <= HEADCTL_MAX_ERROR_TEXT */
#define HEADCTL_ERROR_REPLY_OFF_TEXT 7u        /* printable ASCII, no terminator */
#define HEADCTL_ERROR_REPLY_MIN_SIZE 7u

/* ---- decoded values (not wire images) -------------------------------------------------- */
struct headctl_frame_header {
  uint8_t version;
  uint8_t flags;
  uint8_t type;
  uint8_t sequence;
  uint16_t payload_length;
};

struct headctl_trigger_config {
  uint8_t output;
  uint8_t enabled;
  uint8_t polarity;
  uint32_t pulse_width_us;
  uint32_t delay_us;
};

struct headctl_turntable_status {
  uint8_t state;
  uint8_t homed;
  uint16_t fault;
  uint32_t position_step;
  uint32_t target_step;
  uint32_t steps_per_revolution;
  uint32_t speed_steps_per_s;
};

/* ---- CRC ------------------------------------------------------------------------------- */
/* CRC-32/ISO-HDLC (the CRC of Ethernet, zlib and PNG): reflected polynomial 0xEDB88320,
 * initial value 0xFFFFFFFF, final XOR 0xFFFFFFFF. Check value: the 9 ASCII bytes
 * "123456789" give 0xCBF43926. Feed a frame's bytes [VERSION, end of payload) and store the
 * result little-endian after the payload. Start with crc = 0; chain calls for split data. */
static inline uint32_t headctl_crc32(uint32_t crc, const uint8_t* data, size_t size) {
  size_t i;
  unsigned bit;
  crc = ~crc;
  for (i = 0; i < size; ++i) {
    crc ^= data[i];
    for (bit = 0; bit < 8u; ++bit) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

#ifdef __cplusplus
}  /* extern "C" */
#endif

#endif /* SLS_HEADCTL_PROTOCOL_H */
