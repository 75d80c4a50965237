# Installs the build tree into a scratch prefix, then configures, builds and
# runs tests/consumer against it with find_package(Strata).
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
endfunction()
run(${CMAKE_COMMAND} --install "${STRATA_BUILD_DIR}" --prefix "${WORK_DIR}/prefix")
set(flags "")
if(SANITIZE)
  # Static libraries built with sanitizers need the runtime at link time.
  set(flags "-fsanitize=${SANITIZE}")
endif()
run(${CMAKE_COMMAND} -S "${CONSUMER_SOURCE_DIR}" -B "${WORK_DIR}/build" -G "${GENERATOR}"
    -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix -DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_FLAGS=${flags}"
    "-DCMAKE_EXE_LINKER_FLAGS=${flags}")
run(${CMAKE_COMMAND} --build "${WORK_DIR}/build")
run("${WORK_DIR}/build/consumer")
run("${WORK_DIR}/build/consumer_io" "${WORK_DIR}")
if(EXISTS "${WORK_DIR}/build/consumer_gl")
  # The GL driver (llvmpipe) leaks from code LeakSanitizer cannot name, as
  # in the GPU tests: leak checking off for this program only.
  run(${CMAKE_COMMAND} -E env "ASAN_OPTIONS=detect_leaks=0" "${WORK_DIR}/build/consumer_gl")
endif()
message(STATUS "consumer built and ran against the installed package")
