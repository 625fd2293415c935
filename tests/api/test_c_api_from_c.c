/* The API used from C: compiled as C99, called by test_c_api.cpp. Returns 0 on success,
 * else the number of the first failed check. */
#include <stddef.h>
#include <string.h>

#include <sls/sls.h>

int sls_test_use_api_from_c(void);

int sls_test_use_api_from_c(void) {
  sls_context* context = NULL;
  sls_error* error = NULL;
  sls_context_config config;
  int uses_cuda = -1;
  sls_context_config_init(&config);
  config.device = SLS_DEVICE_CPU;
  if (sls_context_create(SLS_API_VERSION, &config, &context, &error) != SLS_OK) return 1;
  if (context == NULL || error != NULL) return 2;
  if (sls_context_uses_cuda(context, &uses_cuda, NULL) != SLS_OK || uses_cuda != 0) return 3;
  sls_context_destroy(context);
  sls_context_destroy(NULL);
  if (sls_context_create(SLS_MAKE_VERSION(SLS_API_VERSION_MAJOR + 1, 0, 0), NULL, &context, &error) !=
      SLS_ERROR_VERSION_MISMATCH)
    return 4;
  if (error == NULL || sls_error_status(error) != SLS_ERROR_VERSION_MISMATCH) return 5;
  if (strcmp(sls_error_function(error), "sls_context_create") != 0) return 6;
  sls_error_free(error);
  sls_error_free(NULL);
  /* C may store any int in an enum field: one past the C++ enum's range is refused cleanly
   * (the library must not load it as the enum: undefined behaviour in C++). */
  sls_context_config_init(&config);
  config.device = (sls_device_preference)9;
  if (sls_context_create(SLS_API_VERSION, &config, &context, NULL) != SLS_ERROR_INVALID_ARGUMENT) return 7;
  sls_context_config_init(&config);
  config.log_level = (sls_log_level)-3;
  if (sls_context_create(SLS_API_VERSION, &config, &context, NULL) != SLS_ERROR_INVALID_ARGUMENT) return 8;
  return 0;
}
