# The two-camera calibration test's input, made afresh each run: a simulated head of two cameras
# (ci preset, 3 board poses by hand, no turntable views), and an empty scratch folder.
#   cmake -DSLS_TOOL=... -DHEAD=... -DSCRATCH=... -P make_calibration_head.cmake
foreach(variable SLS_TOOL HEAD SCRATCH)
  if(NOT DEFINED ${variable})
    message(FATAL_ERROR "make_calibration_head.cmake: ${variable} is not set")
  endif()
endforeach()
file(REMOVE_RECURSE ${HEAD} ${SCRATCH})
file(MAKE_DIRECTORY ${SCRATCH})
execute_process(
  COMMAND ${SLS_TOOL} -q sim --calibration --cameras 2 --preset ci --hand-poses 3 --turntable-poses 0 --device cpu
          --out ${HEAD}
  RESULT_VARIABLE result ERROR_VARIABLE errors)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "sls sim failed (${result}): ${errors}")
endif()
