# The scan test's input, made afresh each run: a depth-mode recording of the simulated knurled
# knob (ci preset, 36 frames per revolution, coarse reference surface: the test needs the true
# trajectory, not the surface), and an empty scratch folder.
#   cmake -DSLS_TOOL=... -DRECORDING=... -DSCRATCH=... -P make_scan_recording.cmake
foreach(variable SLS_TOOL RECORDING SCRATCH)
  if(NOT DEFINED ${variable})
    message(FATAL_ERROR "make_scan_recording.cmake: ${variable} is not set")
  endif()
endforeach()
file(REMOVE_RECURSE ${RECORDING} ${SCRATCH})
file(MAKE_DIRECTORY ${SCRATCH})
execute_process(
  COMMAND ${SLS_TOOL} -q sim --preset ci --object knurled-knob --frames 36 --mode depth --device cpu
          --reference-spacing-um 1000 --out ${RECORDING}
  RESULT_VARIABLE result ERROR_VARIABLE errors)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "sls sim failed (${result}): ${errors}")
endif()
