# The layer check (cmake/CheckLayers.cmake) passes on the sources and catches each kind of
# violation in tests/data/layer_violation.
function(check_layers root rc_var out_var)
  execute_process(COMMAND ${CMAKE_COMMAND} -DROOT=${root} -P ${SOURCE}/cmake/CheckLayers.cmake
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  set(${rc_var} ${rc} PARENT_SCOPE)
  set(${out_var} "${out}${err}" PARENT_SCOPE)
endfunction()

check_layers(${SOURCE} rc out)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the sources break the layer rules:\n${out}")
endif()

check_layers(${SOURCE}/tests/data/layer_violation rc out)
if(rc EQUAL 0)
  message(FATAL_ERROR "the layer check accepted tests/data/layer_violation:\n${out}")
endif()
foreach(expected
    "preprocess/loader.cpp (layer preprocess) includes \"engine/renderer.h\""
    "preprocess/core/hashing.h (layer preprocess/core) includes <CL/opencl.hpp>"
    "engine/method.cpp (layer engine) includes \"engine/report/bench.h\""
    "engine/methods/ppll.cpp (layer engine/methods) includes \"engine/methods/cells_internal.h\""
    "engine/frontend/cl_pipeline.cpp (layer engine/frontend) includes \"engine/cells/cell_order.h\"")
  string(FIND "${out}" "${expected}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "the layer check did not report: ${expected}\n${out}")
  endif()
endforeach()
string(FIND "${out}" "scene/scene.h\"" wrong)
string(FIND "${out}" "cl_pipeline.h\"" wrong2)
string(FIND "${out}" "frame_runner.h\"" wrong3)
string(FIND "${out}" "batching.h\"" wrong4)
if(NOT wrong EQUAL -1 OR NOT wrong2 EQUAL -1 OR NOT wrong3 EQUAL -1 OR NOT wrong4 EQUAL -1)
  message(FATAL_ERROR "the layer check refused an allowed include:\n${out}")
endif()
message(STATUS "layer check: sources pass, the five violations are caught")
