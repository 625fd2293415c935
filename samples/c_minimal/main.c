/* The smallest slscan C program: create a context, report what it runs on, clean up.
 * Build: cc main.c -lsls. Run: ./sls_c_minimal */
#include <stdio.h>

#include <sls/sls.h>

int main(void) {
  sls_context* context = NULL;
  sls_error* error = NULL;
  int uses_cuda = 0;
  sls_status status = sls_context_create(SLS_API_VERSION, NULL, &context, &error);
  if (status != SLS_OK) {
    fprintf(stderr, "sls_context_create failed: %s: %s\n", sls_status_str(status), sls_error_message(error));
    sls_error_free(error);
    return 1;
  }
  status = sls_context_uses_cuda(context, &uses_cuda, &error);
  if (status != SLS_OK) {
    fprintf(stderr, "%s: %s\n", sls_error_function(error), sls_error_message(error));
    sls_error_free(error);
    sls_context_destroy(context);
    return 1;
  }
  printf("%s\nAPI %d, running on %s\n", sls_get_build_info(), sls_get_api_version(), uses_cuda ? "CUDA" : "CPU");
  sls_context_destroy(context);
  return 0;
}
