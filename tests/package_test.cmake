# `cmake --install` the build into a prefix, then configure, build and run a tiny outside project
# that finds it with find_package(strata) and renders through the public API.
file(REMOVE_RECURSE ${WORK})
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  message(STATUS "${out}")
endfunction()
run(${CMAKE_COMMAND} --install ${BUILD} --prefix ${WORK}/prefix)
run(${CMAKE_COMMAND} -S ${SOURCE} -B ${WORK}/build -DCMAKE_PREFIX_PATH=${WORK}/prefix -DCMAKE_BUILD_TYPE=Release)
run(${CMAKE_COMMAND} --build ${WORK}/build)
run(${WORK}/build/consumer)
run(${WORK}/build/consumer_cxx20)
# The C++ example: both images saved, cells within 2/255 of embree on nearly every pixel.
execute_process(COMMAND ${WORK}/build/render_mesh builtin:demo ${WORK}/example
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT out MATCHES "(99\\.[5-9][0-9]|100\\.00)% of pixels within 2/255" OR
   NOT EXISTS ${WORK}/example-cells.png OR NOT EXISTS ${WORK}/example-embree.png)
  message(FATAL_ERROR "examples/render_mesh.cpp: exit ${rc}, '${out}' '${err}'")
endif()
message(STATUS "${out}")

# The installed program reads the benchmark's meshes from PREFIX/share/strata/models, not from the
# source tree it was built in.
execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=STRATA_MODELS_DIR ${WORK}/prefix/bin/strata
                        bench --suite smoke --methods ppll --frames 1 --orbit 0 --out ${WORK}/bench
                RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
file(READ ${WORK}/bench/results.json results)
if(NOT rc EQUAL 0 OR NOT results MATCHES "${WORK}/prefix/share/strata/models/teapot.obj")
  message(FATAL_ERROR "the installed strata's bench: exit ${rc}, ${err}, not reading "
                      "${WORK}/prefix/share/strata/models")
endif()

# The installed Python module (PREFIX/lib/pythonX.Y/site-packages), alone: it carries the library.
if(PYTHON)
  file(GLOB module ${WORK}/prefix/lib/python*/site-packages/strata*.so)
  if(NOT module)
    message(FATAL_ERROR "cmake --install installed no Python module under ${WORK}/prefix/lib")
  endif()
  get_filename_component(site ${module} DIRECTORY)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${site} ${PYTHON} -c
                          "import strata; print(strata.__version__, strata.__file__)"
                  WORKING_DIRECTORY ${WORK} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0 OR NOT out MATCHES "^[0-9]+\\.[0-9]+\\.[0-9]+ ${site}")
    message(FATAL_ERROR "the installed Python module: exit ${rc}, '${out}' '${err}'")
  endif()
endif()
