// A CUPTI activity tracer for the GPU machine, which has no Nsight Systems (docs/benchmarks.md,
// "A timeline without nsys"). Not built by CMake: build it there and inject it into any
// program; it writes one line per record to $CUPTI_TRACE_OUT:
//   K start_ns end_ns stream 0 kernel_name       (kernels)
//   C start_ns end_ns stream bytes kindN         (copies: 1 host to device, 2 device to host, 8 device)
//   S start_ns end_ns stream bytes memset
//   R start_ns end_ns thread 0 runtime_call      (CUDA runtime calls: where the host waits)
// Build (the record structs' newest versions, as the installed CUPTI names them):
//   H=$(dirname $(find / -xdev -name cupti_activity.h | head -1)); L=$(find / -xdev -name 'libcupti.so*' | head -1)
//   pick() { grep -o "CUpti_Activity$1[0-9]*;" $H/cupti_activity*.h | sed 's/.*://; s/;//' | sort -V | tail -1; }
//   g++ -O2 -shared -fPIC -I$H -I/usr/local/cuda/include -DKERNEL_T=$(pick Kernel) -DMEMCPY_T=$(pick Memcpy) \
//     -DMEMSET_T=$(pick Memset) -o /tmp/libtrace.so scripts/cupti_trace.cpp $L -Wl,-rpath,$(dirname $L)
// Run: CUDA_INJECTION64_PATH=/tmp/libtrace.so CUPTI_TRACE_OUT=/tmp/trace.txt sls bench --preset paper ...
#include <cupti.h>
#include <cstdio>
#include <cstdlib>
#include <cstdint>
#include <cstring>
#include <mutex>

static FILE* g_out = nullptr;
static std::mutex g_mutex;

static void CUPTIAPI buffer_requested(uint8_t** buffer, size_t* size, size_t* max_records) {
  *size = 16 << 20;
  *buffer = static_cast<uint8_t*>(aligned_alloc(8, *size));
  *max_records = 0;
}

static void CUPTIAPI buffer_completed(CUcontext, uint32_t, uint8_t* buffer, size_t, size_t valid) {
  std::lock_guard<std::mutex> lock(g_mutex);
  CUpti_Activity* record = nullptr;
  while (cuptiActivityGetNextRecord(buffer, valid, &record) == CUPTI_SUCCESS) {
    switch (record->kind) {
      case CUPTI_ACTIVITY_KIND_CONCURRENT_KERNEL:
      case CUPTI_ACTIVITY_KIND_KERNEL: {
        auto* k = reinterpret_cast<KERNEL_T*>(record);
        fprintf(g_out, "K %llu %llu %u 0 %s\n", (unsigned long long)k->start, (unsigned long long)k->end,
                k->streamId, k->name);
        break;
      }
      case CUPTI_ACTIVITY_KIND_MEMCPY: {
        auto* m = reinterpret_cast<MEMCPY_T*>(record);
        fprintf(g_out, "C %llu %llu %u %llu kind%d\n", (unsigned long long)m->start, (unsigned long long)m->end,
                m->streamId, (unsigned long long)m->bytes, (int)m->copyKind);
        break;
      }
      case CUPTI_ACTIVITY_KIND_MEMSET: {
        auto* m = reinterpret_cast<MEMSET_T*>(record);
        fprintf(g_out, "S %llu %llu %u %llu memset\n", (unsigned long long)m->start, (unsigned long long)m->end,
                m->streamId, (unsigned long long)m->bytes);
        break;
      }
      case CUPTI_ACTIVITY_KIND_RUNTIME: {
        auto* a = reinterpret_cast<CUpti_ActivityAPI*>(record);
        const char* name = nullptr;
        cuptiGetCallbackName(CUPTI_CB_DOMAIN_RUNTIME_API, a->cbid, &name);
        fprintf(g_out, "R %llu %llu %u 0 %s\n", (unsigned long long)a->start, (unsigned long long)a->end,
                a->threadId, name ? name : "?");
        break;
      }
      default: break;
    }
  }
  free(buffer);
}

static void at_exit() {
  cuptiActivityFlushAll(1);
  if (g_out) fclose(g_out);
}

extern "C" int InitializeInjection(void) {
  const char* path = getenv("CUPTI_TRACE_OUT");
  g_out = fopen(path ? path : "/tmp/cupti_trace.txt", "w");
  if (!g_out) return 0;
  cuptiActivityRegisterCallbacks(buffer_requested, buffer_completed);
  cuptiActivityEnable(CUPTI_ACTIVITY_KIND_CONCURRENT_KERNEL);
  cuptiActivityEnable(CUPTI_ACTIVITY_KIND_MEMCPY);
  cuptiActivityEnable(CUPTI_ACTIVITY_KIND_MEMSET);
  cuptiActivityEnable(CUPTI_ACTIVITY_KIND_RUNTIME);
  atexit(at_exit);
  return 1;
}
