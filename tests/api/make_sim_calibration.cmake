# A calibration test's input, made afresh each run: a simulated calibration capture written by
# `sls sim --calibration` with the test's arguments (on the CPU), and an empty scratch folder
# when SCRATCH is given.
#   cmake -DSLS_TOOL=... -DOUT=... -DSIM_ARGS="--preset;ci;..." [-DSCRATCH=...] -P make_sim_calibration.cmake
foreach(variable SLS_TOOL OUT SIM_ARGS)
  if(NOT DEFINED ${variable})
    message(FATAL_ERROR "make_sim_calibration.cmake: ${variable} is not set")
  endif()
endforeach()
file(REMOVE_RECURSE ${OUT})
if(DEFINED SCRATCH)
  file(REMOVE_RECURSE ${SCRATCH})
  file(MAKE_DIRECTORY ${SCRATCH})
endif()
execute_process(COMMAND ${SLS_TOOL} -q sim --calibration ${SIM_ARGS} --device cpu --out ${OUT}
                RESULT_VARIABLE result ERROR_VARIABLE errors)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "sls sim failed (${result}): ${errors}")
endif()
