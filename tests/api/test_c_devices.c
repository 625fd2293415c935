/* Device enumeration, cameras, projectors and turntables through the C API, from a C99 program,
 * as an OEM would use them: list the devices, open every camera the list names, grab images
 * into our own buffers, drive the simulator's projector and turntable, and get clear status
 * codes for the mistakes. With no hardware connected the list holds the simulator only
 * (sim://); with hardware, each listed camera is opened and grabbed from too (projectors and
 * turntables are driven on the simulator only: a test must not turn a real table).
 * Exit status 0 when every check holds; each failed check prints its line. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sls/sls.h>

#include "c_checks.h"

static void check_list(sls_device_list* list, size_t* count) {
  sls_device_info info;
  const char* problems = NULL;
  int has_hardware = -1;
  size_t i;
  CHECK(sls_device_list_count(list, count, NULL) == SLS_OK);
  CHECK(*count >= 1);
  /* The simulator is always there, first. */
  sls_device_info_init(&info);
  CHECK(sls_device_list_get_info(list, 0, &info, NULL) == SLS_OK);
  CHECK(info.struct_size == sizeof(info));
  CHECK(info.kind == SLS_DEVICE_KIND_SCANNER);
  CHECK(strncmp(info.uri, "sim://", 6) == 0);
  CHECK(info.roles == (SLS_DEVICE_ROLE_CAMERA | SLS_DEVICE_ROLE_PROJECTOR | SLS_DEVICE_ROLE_TURNTABLE));
  CHECK(strlen(info.model) > 0);
  CHECK(info.serial != NULL && info.details != NULL);
  CHECK(sls_device_list_has_hardware(list, &has_hardware, NULL) == SLS_OK);
  CHECK(has_hardware == (*count > 1 ? 1 : 0));
  CHECK(sls_device_list_problems(list, &problems, NULL) == SLS_OK && problems != NULL);
  for (i = 0; i < *count; ++i) {
    sls_device_info_init(&info);
    CHECK(sls_device_list_get_info(list, i, &info, NULL) == SLS_OK);
    CHECK(info.uri != NULL && strstr(info.uri, "://") != NULL);
    CHECK(info.roles != 0);
    CHECK(info.kind == SLS_DEVICE_KIND_SCANNER || i > 0);
  }
  /* Past the end, and an uninitialised struct. */
  sls_device_info_init(&info);
  CHECK_ERROR(sls_device_list_get_info(list, *count, &info, &error_), SLS_ERROR_INVALID_ARGUMENT, "past");
  info.struct_size = 3;
  CHECK_ERROR(sls_device_list_get_info(list, 0, &info, &error_), SLS_ERROR_INVALID_ARGUMENT, "sls_device_info_init");
}

/* A caller compiled against newer headers (a larger struct) gets this library's fields and
 * nothing is written past them. */
static void check_versioning(sls_device_list* list) {
  unsigned char storage[sizeof(sls_device_info) + 32];
  sls_device_info* info = (sls_device_info*)(void*)storage;
  size_t i;
  memset(storage, 0xA5, sizeof(storage));
  info->struct_size = sizeof(storage);
  CHECK(sls_device_list_get_info(list, 0, info, NULL) == SLS_OK);
  CHECK(info->struct_size == sizeof(storage));
  CHECK(strncmp(info->uri, "sim://", 6) == 0);
  for (i = sizeof(sls_device_info); i < sizeof(storage); ++i) CHECK(storage[i] == 0xA5);
}

static void check_camera(sls_context* context, const char* uri) {
  sls_camera* camera = NULL;
  sls_camera_info info;
  sls_frame_info frame;
  uint16_t* pixels;
  size_t count, i, nonzero = 0;
  uint64_t first_id;
  int max_value;
  sls_error* error = NULL;
  if (sls_camera_open(context, uri, &camera, &error) != SLS_OK) {
    fprintf(stderr, "%s: open failed: %s\n", uri, sls_error_message(error));
    sls_error_free(error);
    ++failures;
    return;
  }
  sls_camera_info_init(&info);
  CHECK(sls_camera_get_info(camera, &info, NULL) == SLS_OK);
  CHECK(info.width > 0 && info.height > 0);
  CHECK(info.bit_depth >= 8 && info.bit_depth <= 16);
  CHECK(strlen(info.uri) > 0 && strlen(info.model) > 0);
  count = (size_t)info.width * (size_t)info.height;
  pixels = (uint16_t*)malloc((count + 1) * sizeof(uint16_t));
  CHECK(pixels != NULL);
  if (pixels == NULL) {
    sls_camera_close(camera);
    return;
  }
  /* A buffer one pixel short is refused before anything is captured, and left as it was. */
  for (i = 0; i <= count; ++i) pixels[i] = 0xBEEF;
  CHECK_ERROR(sls_camera_grab(camera, 1000, pixels, count - 1, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "needs");
  CHECK(pixels[0] == 0xBEEF && pixels[count - 2] == 0xBEEF);

  sls_frame_info_init(&frame);
  CHECK(sls_camera_grab(camera, 5000, pixels, count, &frame, NULL) == SLS_OK);
  CHECK(frame.width == info.width && frame.height == info.height && frame.bit_depth == info.bit_depth);
  CHECK(pixels[count] == 0xBEEF); /* nothing past width x height */
  max_value = (1 << info.bit_depth) - 1;
  for (i = 0; i < count; ++i) {
    if (pixels[i] > max_value) break;
    if (pixels[i] != 0) ++nonzero;
  }
  CHECK(i == count); /* every value within the bit depth */
  CHECK(nonzero > 0); /* an image, not an untouched or cleared buffer */
  first_id = frame.frame_id;
  CHECK(sls_camera_grab(camera, 5000, pixels, count, &frame, NULL) == SLS_OK);
  CHECK(frame.frame_id > first_id); /* one call, one new image */
  CHECK(sls_camera_grab(camera, 5000, pixels, count, NULL, NULL) == SLS_OK); /* frame info is optional */
  frame.struct_size = 1;
  CHECK_ERROR(sls_camera_grab(camera, 5000, pixels, count, &frame, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "sls_frame_info_init");
  CHECK_ERROR(sls_camera_grab(camera, -1, pixels, count, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "timeout_ms");
  CHECK_ERROR(sls_camera_set_exposure_us(camera, 0.0, &error_), SLS_ERROR_INVALID_ARGUMENT, "exposure_us");
  free(pixels);
  sls_camera_close(camera);
}

static void check_camera_mistakes(sls_context* context) {
  sls_camera* camera = NULL;
  uint16_t pixel = 0;
  CHECK_ERROR(sls_camera_open(context, "firewire://0", &camera, &error_), SLS_ERROR_UNSUPPORTED, "firewire://0");
  CHECK(camera == NULL);
  CHECK_ERROR(sls_camera_open(context, "dlpc350://", &camera, &error_), SLS_ERROR_INVALID_ARGUMENT, "dlpc350://");
  CHECK_ERROR(sls_camera_open(context, "sim://no-such-object?preset=ci", &camera, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "no-such-object");
  CHECK_ERROR(sls_camera_open(context, NULL, &camera, &error_), SLS_ERROR_INVALID_ARGUMENT, "uri");
  CHECK_ERROR(sls_camera_open(NULL, "sim://plane?preset=ci", &camera, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "context");
  CHECK_ERROR(sls_camera_open(context, "sim://plane?preset=ci", NULL, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "camera");
  CHECK_ERROR(sls_camera_grab(NULL, 10, &pixel, 1, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "camera");
  CHECK(sls_camera_open(context, "sim://plane?preset=ci", &camera, NULL) == SLS_OK);
  CHECK_ERROR(sls_camera_grab(camera, 10, NULL, 1, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "pixels");
  sls_camera_close(camera);
  sls_camera_close(NULL);
}

/* The mean of one grabbed image (-1 when the grab fails). */
static double mean_of_grab(sls_camera* camera, uint16_t* pixels, size_t count) {
  size_t i;
  double sum = 0.0;
  if (sls_camera_grab(camera, 5000, pixels, count, NULL, NULL) != SLS_OK) return -1.0;
  for (i = 0; i < count; ++i) sum += pixels[i];
  return sum / (double)count;
}

/* A sim:// projector: its info, the scan's pattern set, patterns shown and dark; and, opened
 * with the same URI as a camera, one simulated scanner: the camera sees the white pattern
 * brighter than the black one. */
static void check_sim_projector(sls_context* context, const char* uri) {
  sls_projector* projector = NULL;
  sls_camera* camera = NULL;
  sls_projector_info info;
  sls_camera_info camera_info;
  int count = 0, current = -2;
  uint16_t* pixels = NULL;
  size_t pixel_count;
  double white, black;
  CHECK(sls_projector_open(context, uri, &projector, NULL) == SLS_OK);
  if (projector == NULL) return;
  sls_projector_info_init(&info);
  CHECK(sls_projector_get_info(projector, &info, NULL) == SLS_OK);
  CHECK(strncmp(info.uri, "sim://", 6) == 0);
  CHECK(strlen(info.model) > 0 && info.firmware != NULL);
  CHECK(info.width > 0 && info.height > 0);
  info.struct_size = 2;
  CHECK_ERROR(sls_projector_get_info(projector, &info, &error_), SLS_ERROR_INVALID_ARGUMENT, "sls_projector_info_init");

  CHECK(sls_projector_load_scan_patterns(projector, &count, NULL) == SLS_OK);
  CHECK(count > 2); /* white, black, then the Gray code and phase patterns */
  CHECK(sls_projector_load_scan_patterns(projector, NULL, NULL) == SLS_OK); /* the count is optional */
  CHECK(sls_projector_show_pattern(projector, count - 1, NULL) == SLS_OK);
  CHECK(sls_projector_get_current_pattern(projector, &current, NULL) == SLS_OK && current == count - 1);
  CHECK_ERROR(sls_projector_show_pattern(projector, count, &error_), SLS_ERROR_INVALID_ARGUMENT, "pattern");
  CHECK_ERROR(sls_projector_show_pattern(projector, -1, &error_), SLS_ERROR_INVALID_ARGUMENT, "pattern");
  CHECK(sls_projector_go_dark(projector, NULL) == SLS_OK);
  CHECK(sls_projector_get_current_pattern(projector, &current, NULL) == SLS_OK && current == -1);

  CHECK(sls_camera_open(context, uri, &camera, NULL) == SLS_OK);
  sls_camera_info_init(&camera_info);
  if (camera != NULL && sls_camera_get_info(camera, &camera_info, NULL) == SLS_OK) {
    pixel_count = (size_t)camera_info.width * (size_t)camera_info.height;
    pixels = (uint16_t*)malloc(pixel_count * sizeof(uint16_t));
    CHECK(pixels != NULL);
    if (pixels != NULL) {
      CHECK(sls_projector_show_pattern(projector, 0, NULL) == SLS_OK);
      white = mean_of_grab(camera, pixels, pixel_count);
      CHECK(sls_projector_show_pattern(projector, 1, NULL) == SLS_OK);
      black = mean_of_grab(camera, pixels, pixel_count);
      CHECK(white >= 0.0 && black >= 0.0);
      CHECK(white > 1.5 * black);
      free(pixels);
    }
  }
  sls_camera_close(camera);
  sls_projector_close(projector);
  sls_projector_close(NULL);

  CHECK_ERROR(sls_projector_open(context, "gige://192.0.2.1", &projector, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "gige://192.0.2.1");
  CHECK(projector == NULL);
  CHECK_ERROR(sls_projector_open(context, "firewire://0", &projector, &error_), SLS_ERROR_UNSUPPORTED, "firewire://0");
  CHECK_ERROR(sls_projector_open(NULL, uri, &projector, &error_), SLS_ERROR_INVALID_ARGUMENT, "context");
  CHECK_ERROR(sls_projector_open(context, NULL, &projector, &error_), SLS_ERROR_INVALID_ARGUMENT, "uri");
  CHECK_ERROR(sls_projector_open(context, uri, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "projector");
  CHECK_ERROR(sls_projector_show_pattern(NULL, 0, &error_), SLS_ERROR_INVALID_ARGUMENT, "projector");
  CHECK_ERROR(sls_projector_get_current_pattern(NULL, &current, &error_), SLS_ERROR_INVALID_ARGUMENT, "projector");
  CHECK_ERROR(sls_projector_go_dark(NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "projector");
  CHECK_ERROR(sls_projector_load_scan_patterns(NULL, &count, &error_), SLS_ERROR_INVALID_ARGUMENT, "projector");
}

/* A sim:// turntable: homed, moved, its position read back to within a step. */
static void check_sim_turntable(sls_context* context, const char* uri) {
  sls_turntable* table = NULL;
  int steps = 0;
  double angle = -1.0, step_deg;
  CHECK(sls_turntable_open(context, uri, &table, NULL) == SLS_OK);
  if (table == NULL) return;
  CHECK(sls_turntable_get_steps_per_revolution(table, &steps, NULL) == SLS_OK);
  CHECK(steps > 0);
  step_deg = 360.0 / (double)(steps > 0 ? steps : 1);
  /* The simulated table, like the head controller's, refuses to move before it is homed. */
  CHECK_ERROR(sls_turntable_move_to_deg(table, 90.0, 1000, &error_), SLS_ERROR_INVALID_ARGUMENT, "homed");
  CHECK(sls_turntable_home(table, 1000, NULL) == SLS_OK);
  CHECK(sls_turntable_get_position_deg(table, &angle, NULL) == SLS_OK);
  CHECK(angle == 0.0);
  CHECK(sls_turntable_move_to_deg(table, 90.0, 1000, NULL) == SLS_OK);
  CHECK(sls_turntable_get_position_deg(table, &angle, NULL) == SLS_OK);
  CHECK(fabs(angle - 90.0) <= 0.5 * step_deg + 1e-9);
  CHECK(sls_turntable_move_to_deg(table, 359.0, 1000, NULL) == SLS_OK);
  CHECK(sls_turntable_get_position_deg(table, &angle, NULL) == SLS_OK);
  CHECK(fabs(angle - 359.0) <= 0.5 * step_deg + 1e-9);
  CHECK_ERROR(sls_turntable_move_to_deg(table, 360.0, 1000, &error_), SLS_ERROR_INVALID_ARGUMENT, "angle_deg");
  CHECK_ERROR(sls_turntable_move_to_deg(table, -1.0, 1000, &error_), SLS_ERROR_INVALID_ARGUMENT, "angle_deg");
  CHECK_ERROR(sls_turntable_move_to_deg(table, 10.0, 0, &error_), SLS_ERROR_INVALID_ARGUMENT, "timeout_ms");
  CHECK_ERROR(sls_turntable_home(table, 0, &error_), SLS_ERROR_INVALID_ARGUMENT, "timeout_ms");
  sls_turntable_close(table);
  sls_turntable_close(NULL);

  CHECK_ERROR(sls_turntable_open(context, "dlpc350://", &table, &error_), SLS_ERROR_INVALID_ARGUMENT, "dlpc350://");
  CHECK(table == NULL);
  CHECK_ERROR(sls_turntable_open(NULL, uri, &table, &error_), SLS_ERROR_INVALID_ARGUMENT, "context");
  CHECK_ERROR(sls_turntable_open(context, NULL, &table, &error_), SLS_ERROR_INVALID_ARGUMENT, "uri");
  CHECK_ERROR(sls_turntable_open(context, uri, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "turntable");
  CHECK_ERROR(sls_turntable_home(NULL, 1000, &error_), SLS_ERROR_INVALID_ARGUMENT, "turntable");
  CHECK_ERROR(sls_turntable_move_to_deg(NULL, 1.0, 1000, &error_), SLS_ERROR_INVALID_ARGUMENT, "turntable");
  CHECK_ERROR(sls_turntable_get_position_deg(NULL, &angle, &error_), SLS_ERROR_INVALID_ARGUMENT, "turntable");
  CHECK_ERROR(sls_turntable_get_steps_per_revolution(NULL, &steps, &error_), SLS_ERROR_INVALID_ARGUMENT, "turntable");
}

int main(void) {
  sls_context* context = NULL;
  sls_context_config config;
  sls_device_list* list = NULL;
  size_t count = 0, i;
  sls_context_config_init(&config);
  config.device = SLS_DEVICE_CPU;
  if (sls_context_create(SLS_API_VERSION, &config, &context, NULL) != SLS_OK) {
    fprintf(stderr, "no context\n");
    return 1;
  }
  CHECK(sls_device_list_create(context, &list, NULL) == SLS_OK);
  if (list != NULL) {
    check_list(list, &count);
    check_versioning(list);
    /* Every listed device that is a camera opens by its URI and grabs. */
    for (i = 0; i < count; ++i) {
      sls_device_info info;
      sls_device_info_init(&info);
      if (sls_device_list_get_info(list, i, &info, NULL) == SLS_OK && (info.roles & SLS_DEVICE_ROLE_CAMERA) != 0) {
        printf("camera %s\n", info.uri);
        check_camera(context, info.uri);
      }
    }
  }
  sls_device_list_destroy(list);
  sls_device_list_destroy(NULL);
  CHECK_ERROR(sls_device_list_create(context, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "list");
  CHECK_ERROR(sls_device_list_create(NULL, &list, &error_), SLS_ERROR_INVALID_ARGUMENT, "context");
  CHECK(list == NULL);
  CHECK_ERROR(sls_device_list_count(NULL, &count, &error_), SLS_ERROR_INVALID_ARGUMENT, "list");
  check_camera_mistakes(context);
  check_sim_projector(context, "sim://knurled-screw?preset=ci");
  check_sim_turntable(context, "sim://knurled-screw?preset=ci");
  sls_context_destroy(context);
  if (failures != 0) fprintf(stderr, "%d check(s) failed\n", failures);
  else printf("all checks passed\n");
  return failures == 0 ? 0 : 1;
}
