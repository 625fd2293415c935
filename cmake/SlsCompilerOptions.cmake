# Warning and sanitizer flags, applied per target through sls_target_defaults().

set(SLS_CXX_WARNINGS -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
    -Wold-style-cast -Wcast-align -Woverloaded-virtual -Wconversion -Wsign-conversion
    -Wnull-dereference -Wdouble-promotion -Wformat=2 -Wimplicit-fallthrough)
set(SLS_C_WARNINGS -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wstrict-prototypes)
# On aarch64 GCC notes that passing some aggregates changed ABI in GCC 10.1 (-Wpsabi): about
# linking with objects built by GCC 9 or older, which an SDK built as a whole never does.
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
  list(APPEND SLS_CXX_WARNINGS -Wno-psabi)
endif()

# ASan + UBSan, less UBSan's type-mismatch checks (null, alignment): GCC emits one per pointer
# use, a third of this build's compile time (docs/benchmarks.md, "CI time"). What they would
# catch is caught elsewhere: a null pointer read or written stops the test as ASan's SEGV report,
# and the code that reads bytes from files and devices (the parsers) runs under clang's full
# UBSan, these checks included, in the fuzz targets (tests/fuzz).
if(SLS_SANITIZE)
  add_compile_options($<$<COMPILE_LANGUAGE:C,CXX>:-fsanitize=address,undefined>
                      $<$<COMPILE_LANGUAGE:C,CXX>:-fno-sanitize=null,alignment>
                      $<$<COMPILE_LANGUAGE:C,CXX>:-fno-omit-frame-pointer>
                      $<$<COMPILE_LANGUAGE:C,CXX>:-fno-sanitize-recover=undefined>)
  add_link_options(-fsanitize=address,undefined)
endif()

# ThreadSanitizer: the code that runs threads (capture, the recording writer's encoders, the
# online-deformation worker, the Aravis and USB event threads), tested by the `threads` label.
# - It cannot be combined with ASan (each owns the shadow memory).
# - CPU only: the CUDA runtime's own threads and driver mappings are not instrumented and
#   TSan reports noise in them; the GPU code is checked by compute-sanitizer (scripts/gpu-check).
# - OpenMP stays compiled in (the code under test is the code we ship) but the tests run with
#   OMP_NUM_THREADS=1 (scripts/test): libgomp is not built with TSan, so its barriers and
#   futex-based locks are invisible to it and every parallel region would be reported as a
#   race between its workers. One OpenMP thread per region keeps those reports out without a
#   suppression that could also hide one of ours; the OpenMP loops themselves are data-parallel
#   over disjoint output and are covered by the ASan pass.
if(SLS_SANITIZE_THREAD)
  if(SLS_SANITIZE)
    message(FATAL_ERROR "SLS_SANITIZE (ASan+UBSan) and SLS_SANITIZE_THREAD (TSan) cannot be combined: use two build folders")
  endif()
  if(SLS_WITH_CUDA)
    message(STATUS "SLS_SANITIZE_THREAD: CUDA backends off (compute-sanitizer checks them: scripts/gpu-check)")
    set(SLS_WITH_CUDA OFF CACHE BOOL "Build CUDA backends when nvcc is found" FORCE)
  endif()
  add_compile_options($<$<COMPILE_LANGUAGE:C,CXX>:-fsanitize=thread>
                      $<$<COMPILE_LANGUAGE:C,CXX>:-fno-omit-frame-pointer>)
  add_link_options(-fsanitize=thread)
endif()

# Applies the project's warnings (and -Werror when SLS_WERROR) to one of our targets.
# Third-party headers come in as SYSTEM includes so their warnings never fail our build.
function(sls_target_defaults target)
  target_compile_options(${target} PRIVATE
    $<$<COMPILE_LANGUAGE:CXX>:${SLS_CXX_WARNINGS}>
    $<$<COMPILE_LANGUAGE:C>:${SLS_C_WARNINGS}>
    $<$<COMPILE_LANGUAGE:CUDA>:-Xcompiler=-Wall,-Wextra>
    # parallel_for's bodies are lambdas that run on the device (sdk/core/parallel_for.h).
    $<$<COMPILE_LANGUAGE:CUDA>:--extended-lambda>)
  if(SLS_WERROR)
    target_compile_options(${target} PRIVATE
      $<$<COMPILE_LANGUAGE:C,CXX>:-Werror>
      $<$<COMPILE_LANGUAGE:CUDA>:-Werror=all-warnings -Xcompiler=-Werror>)
  endif()
  target_include_directories(${target} PUBLIC $<BUILD_INTERFACE:${SLS_SOURCE_ROOT}>)
endfunction()

