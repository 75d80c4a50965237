# Installs the build tree into a scratch prefix, then, against that prefix
# alone: configures, builds and runs the C++ consumer (io, baker, gl and
# examples/engine.cpp), the runtime-only consumer, the C99 project on the
# shared C library (examples/engine.c), and the same C program built with
# pkg-config.  Both example programs must draw the vertices the installed
# strata-reconstruct writes for a rig the installed strata-demo bakes.
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  set(run_output "${out}" PARENT_SCOPE)
endfunction()
set(prefix "${WORK_DIR}/prefix")
run(${CMAKE_COMMAND} --install "${STRATA_BUILD_DIR}" --prefix "${prefix}")
set(flags "")
if(SANITIZE)
  # Libraries built with sanitizers need the runtime at link time.
  set(flags "-fsanitize=${SANITIZE}")
endif()
set(common -G "${GENERATOR}" -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_BUILD_TYPE=Release
           "-DEXAMPLES_DIR=${EXAMPLES_DIR}" "-DCMAKE_EXE_LINKER_FLAGS=${flags}")
run(${CMAKE_COMMAND} -S "${CONSUMER_SOURCE_DIR}" -B "${WORK_DIR}/build" ${common} "-DCMAKE_CXX_FLAGS=${flags}")
run(${CMAKE_COMMAND} --build "${WORK_DIR}/build")
run(${CMAKE_COMMAND} -S "${CONSUMER_SOURCE_DIR}/runtime" -B "${WORK_DIR}/runtime" ${common} "-DCMAKE_CXX_FLAGS=${flags}")
run(${CMAKE_COMMAND} --build "${WORK_DIR}/runtime")
run(${CMAKE_COMMAND} -S "${CONSUMER_SOURCE_DIR}/c" -B "${WORK_DIR}/c" ${common} "-DCMAKE_C_FLAGS=${flags}")
run(${CMAKE_COMMAND} --build "${WORK_DIR}/c")
# pkg-config, the way a Makefile or Meson project finds the C library.
run(${CMAKE_COMMAND} -E env "PKG_CONFIG_PATH=${prefix}/lib/pkgconfig" pkg-config --cflags --libs strata)
string(STRIP "${run_output}" pc)
separate_arguments(pc UNIX_COMMAND "${pc}")
separate_arguments(sanitize UNIX_COMMAND "${flags}")
run(cc -std=c99 -Wall -Wextra -pedantic -Werror ${sanitize} "${EXAMPLES_DIR}/engine.c" ${pc}
    "-Wl,-rpath,${prefix}/lib" -o "${WORK_DIR}/engine_pc")

run("${WORK_DIR}/runtime/consumer_runtime")
run("${WORK_DIR}/build/consumer_io" "${WORK_DIR}")
if(EXISTS "${WORK_DIR}/build/consumer_gl")
  # The GL driver (llvmpipe) leaks from code LeakSanitizer cannot name, as
  # in the GPU tests: leak checking off for this program only.
  run(${CMAKE_COMMAND} -E env "ASAN_OPTIONS=detect_leaks=0" "${WORK_DIR}/build/consumer_gl")
endif()

# A rig from the installed tools, and the installed reconstruction of it.
run("${prefix}/bin/strata-demo" --out "${WORK_DIR}/demo" --max-level 3 --size 256)
run("${WORK_DIR}/build/consumer_bake" "${WORK_DIR}/demo/head_highres.ply" "${WORK_DIR}/demo/head.glb"
    "${WORK_DIR}/baked.glb")
set(rig "${WORK_DIR}/demo/head.glb")
run("${prefix}/bin/strata-reconstruct" "${rig}" -o "${WORK_DIR}/reference.obj")
file(STRINGS "${WORK_DIR}/reference.obj" expected REGEX "^v ")
list(LENGTH expected count)
if(count LESS 600)
  message(FATAL_ERROR "the reference has only ${count} vertices")
endif()
foreach(exe "${WORK_DIR}/build/engine" "${WORK_DIR}/c/engine_c" "${WORK_DIR}/engine_pc")
  run("${exe}" "${rig}" "${WORK_DIR}/example.obj")
  file(STRINGS "${WORK_DIR}/example.obj" got REGEX "^v ")
  if(NOT got STREQUAL expected)
    message(FATAL_ERROR "${exe} drew other vertices than strata-reconstruct")
  endif()
  file(REMOVE "${WORK_DIR}/example.obj")
endforeach()
message(STATUS "consumers built and ran against the installed package; ${count} vertices equal strata-reconstruct's")
