/* Checks for the C API's tests written in C (C99): CHECK counts a failed condition,
 * CHECK_ERROR a call that must fail with a given status and a message mentioning a part.
 * Each test's main() returns `failures != 0`. */
#ifndef SLS_TESTS_API_C_CHECKS_H
#define SLS_TESTS_API_C_CHECKS_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sls/sls.h>

static int failures = 0;

#define CHECK(condition)                                                              \
  do {                                                                                \
    if (!(condition)) {                                                               \
      fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #condition); \
      ++failures;                                                                     \
    }                                                                                 \
  } while (0)

/* The status of a call, and its error's message containing `part` (when part is not NULL). */
static void check_error(sls_status got, sls_status expected, sls_error* error, const char* part, int line) {
  if (got != expected) {
    fprintf(stderr, "%s:%d: status %s (%d), expected %s: %s\n", __FILE__, line, sls_status_str(got), (int)got,
            sls_status_str(expected), sls_error_message(error));
    ++failures;
  } else if (error == NULL || sls_error_status(error) != expected) {
    fprintf(stderr, "%s:%d: no sls_error with status %s\n", __FILE__, line, sls_status_str(expected));
    ++failures;
  } else if (part != NULL && strstr(sls_error_message(error), part) == NULL) {
    fprintf(stderr, "%s:%d: message \"%s\" does not mention \"%s\"\n", __FILE__, line, sls_error_message(error),
            part);
    ++failures;
  }
  sls_error_free(error);
}

/* 1 when the file can be read and contains `text` (files of a few kilobytes). */
static inline int file_contains(const char* path, const char* text) {
  char buffer[65536];
  size_t length;
  FILE* file = fopen(path, "rb");
  if (file == NULL) return 0;
  length = fread(buffer, 1, sizeof(buffer) - 1, file);
  fclose(file);
  buffer[length] = '\0';
  return strstr(buffer, text) != NULL;
}

/* `call` must use `&error_` as its sls_error** argument. */
#define CHECK_ERROR(call, expected, part)                         \
  do {                                                            \
    sls_error* error_ = NULL;                                     \
    sls_status status_ = (call);                                  \
    check_error(status_, (expected), error_, (part), __LINE__);  \
  } while (0)

/* A call that must succeed; prints its error otherwise. */
static inline int succeeded(sls_status status, sls_error* error, int line) {
  if (status == SLS_OK) return 1;
  fprintf(stderr, "%s:%d: %s: %s\n", __FILE__, line, sls_status_str(status), sls_error_message(error));
  sls_error_free(error);
  ++failures;
  return 0;
}
/* `call` must use `&error_` as its sls_error** argument. */
#define CHECK_OK(call)                    \
  do {                                    \
    sls_error* error_ = NULL;             \
    sls_status status_ = (call);          \
    succeeded(status_, error_, __LINE__); \
  } while (0)

/* folder/name in a new malloc'ed string (the caller frees it). */
static inline char* path_join(const char* folder, const char* name) {
  size_t length = strlen(folder) + strlen(name) + 2;
  char* path = (char*)malloc(length);
  if (path == NULL) exit(2);
  sprintf(path, "%s/%s", folder, name);
  return path;
}

#endif /* SLS_TESTS_API_C_CHECKS_H */
