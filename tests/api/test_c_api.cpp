#include <sls/sls.h>

#include <cstring>
#include <set>
#include <string>

#include <gtest/gtest.h>

extern "C" int sls_test_use_api_from_c(void);

namespace {

const sls_status kAllErrors[] = {
    SLS_ERROR_INVALID_ARGUMENT, SLS_ERROR_IO,      SLS_ERROR_FORMAT,    SLS_ERROR_NOT_FOUND,
    SLS_ERROR_OUT_OF_MEMORY,    SLS_ERROR_UNSUPPORTED, SLS_ERROR_VERSION_MISMATCH, SLS_ERROR_DEVICE,
    SLS_ERROR_TIMEOUT,          SLS_ERROR_CANCELLED, SLS_ERROR_BUSY,      SLS_ERROR_INTERNAL};

TEST(CApi, EveryStatusHasItsOwnName) {
  std::set<std::string> names;
  EXPECT_STREQ(sls_status_str(SLS_OK), "ok");
  for (const sls_status status : kAllErrors) {
    EXPECT_LT(status, 0);
    const std::string name = sls_status_str(status);
    EXPECT_NE(name, "unknown status") << status;
    names.insert(name);
  }
  EXPECT_EQ(names.size(), std::size(kAllErrors));
  EXPECT_STREQ(sls_status_str(static_cast<sls_status>(-77)), "unknown status");
}

TEST(CApi, VersionAndBuildInfo) {
  EXPECT_EQ(sls_get_api_version(), SLS_API_VERSION);
  EXPECT_NE(std::strstr(sls_get_build_info(), "slscan"), nullptr);
}

TEST(CApi, ContextWithDefaultsAndExplicitCpu) {
  sls_context* context = nullptr;
  ASSERT_EQ(sls_context_create(SLS_API_VERSION, nullptr, &context, nullptr), SLS_OK);
  ASSERT_NE(context, nullptr);
  int uses_cuda = -1;
  int cuda_count = -1;
  ASSERT_EQ(sls_context_uses_cuda(context, &uses_cuda, nullptr), SLS_OK);
  ASSERT_EQ(sls_get_cuda_device_count(&cuda_count, nullptr), SLS_OK);
  EXPECT_EQ(uses_cuda, cuda_count > 0 ? 1 : 0);  // AUTO picks a GPU exactly when one is usable
  sls_context_destroy(context);
}

TEST(CApi, VersionMismatchIsRefusedWithAMessage) {
  for (const int version : {SLS_MAKE_VERSION(SLS_API_VERSION_MAJOR + 1, 0, 0),
                            SLS_MAKE_VERSION(SLS_API_VERSION_MAJOR, SLS_API_VERSION_MINOR + 1, 0), -1}) {
    sls_context* context = nullptr;
    sls_error* error = nullptr;
    EXPECT_EQ(sls_context_create(version, nullptr, &context, &error), SLS_ERROR_VERSION_MISMATCH);
    EXPECT_EQ(context, nullptr);
    ASSERT_NE(error, nullptr);
    EXPECT_EQ(sls_error_status(error), SLS_ERROR_VERSION_MISMATCH);
    EXPECT_NE(std::strstr(sls_error_message(error), "API"), nullptr) << sls_error_message(error);
    sls_error_free(error);
  }
}

TEST(CApi, BadArgumentsGiveInvalidArgumentNotACrash) {
  sls_error* error = nullptr;
  EXPECT_EQ(sls_context_create(SLS_API_VERSION, nullptr, nullptr, &error), SLS_ERROR_INVALID_ARGUMENT);
  ASSERT_NE(error, nullptr);
  EXPECT_STREQ(sls_error_function(error), "sls_context_create");
  sls_error_free(error);

  sls_context_config config;
  sls_context_config_init(&config);
  config.struct_size = 3;  // not initialised by sls_context_config_init
  sls_context* context = nullptr;
  EXPECT_EQ(sls_context_create(SLS_API_VERSION, &config, &context, nullptr), SLS_ERROR_INVALID_ARGUMENT);
  sls_context_config_init(&config);
  config.log_level = static_cast<sls_log_level>(7);
  EXPECT_EQ(sls_context_create(SLS_API_VERSION, &config, &context, nullptr), SLS_ERROR_INVALID_ARGUMENT);
  sls_context_config_init(&config);
  config.cuda_device_id = -2;
  EXPECT_EQ(sls_context_create(SLS_API_VERSION, &config, &context, nullptr), SLS_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(context, nullptr);
  EXPECT_EQ(sls_context_uses_cuda(nullptr, nullptr, nullptr), SLS_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(sls_get_cuda_device_count(nullptr, nullptr), SLS_ERROR_INVALID_ARGUMENT);
}

TEST(CApi, CudaDemandedWithoutAGpuIsAClearError) {
  int cuda_count = 0;
  ASSERT_EQ(sls_get_cuda_device_count(&cuda_count, nullptr), SLS_OK);
  sls_context_config config;
  sls_context_config_init(&config);
  config.device = SLS_DEVICE_CUDA;
  config.cuda_device_id = cuda_count;  // one past the last GPU
  sls_context* context = nullptr;
  sls_error* error = nullptr;
  const sls_status status = sls_context_create(SLS_API_VERSION, &config, &context, &error);
  EXPECT_TRUE(status == SLS_ERROR_DEVICE || status == SLS_ERROR_UNSUPPORTED) << sls_status_str(status);
  ASSERT_NE(error, nullptr);
  EXPECT_NE(std::strstr(sls_error_message(error), "cuda"), nullptr) << sls_error_message(error);
  sls_error_free(error);
}

TEST(CApi, OlderConfigStructKeepsDefaultsForMissingFields) {
  // A caller compiled with a config that ended before a later field: only its prefix counts.
  sls_context_config config;
  sls_context_config_init(&config);
  config.device = SLS_DEVICE_CPU;
  config.struct_size = sizeof(config) + 8;  // from newer headers: still accepted
  sls_context* context = nullptr;
  ASSERT_EQ(sls_context_create(SLS_API_VERSION, &config, &context, nullptr), SLS_OK);
  sls_context_destroy(context);
}

TEST(CApi, UsableFromC) { EXPECT_EQ(sls_test_use_api_from_c(), 0); }

}  // namespace
