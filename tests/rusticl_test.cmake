# strata on a second OpenCL implementation: Mesa's rusticl with its llvmpipe CPU device (Debian
# package mesa-opencl-icd, shown only with RUSTICL_ENABLE=llvmpipe), which lacks 64-bit atomics,
# so every method runs its path without them. `strata info` must say so for every method; each
# method's image and fragment count must match PoCL's on the same path (--atomics 32) on a mesh
# and the textured scene, and every exact method must be within 2/255 of embree on 99.5% of
# pixels. Fails, naming the method and scene, otherwise.
# Left out until strata keeps its serial kernels' loops under llvmpipe's limit of 65,535
# iterations per work-item (docs/results/devices.md): cells and octree above 32x32 pixels and
# scenes of many triangles (builtin:spheres:N), where llvmpipe ends the loops early.
cmake_minimum_required(VERSION 3.19)  # string(JSON)
file(MAKE_DIRECTORY ${WORK})
set(ENV{RUSTICL_ENABLE} llvmpipe)
include(${CMAKE_CURRENT_LIST_DIR}/cli_expect.cmake)
strata_methods(methods)
list(REMOVE_ITEM methods embree cells octree)
set(exact opaque ppll abuffer mdts mdts32 dp ddp)  # bdp and bdp2 lose colliding fragments

execute_process(COMMAND ${STRATA} info --device llvmpipe RESULT_VARIABLE rc OUTPUT_VARIABLE info
                ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "strata info --device llvmpipe: exit ${rc}\n${info}\n${err}")
endif()
strata_methods(all_methods)
list(REMOVE_ITEM all_methods embree)
foreach(m ${all_methods})
  if(NOT info MATCHES "\n  ${m} +runs without 64-bit atomics\n")
    message(SEND_ERROR "strata info on llvmpipe does not say that ${m} runs without 64-bit atomics:\n${info}")
  endif()
endforeach()

# `strata render SCENE -m METHOD` with ARGN into WORK/NAME.png and its stats; returns the
# fragment count in `fragments`.
function(render name scene method)
  execute_process(COMMAND ${STRATA} render ${scene} -m ${method} -s 64x64 ${ARGN}
                          -o ${WORK}/${name}.png --stats ${WORK}/${name}.json
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name}: exit ${rc}\n${out}\n${err}")
  endif()
  file(READ ${WORK}/${name}.json json)
  string(JSON n GET "${json}" fragments)
  set(fragments ${n} PARENT_SCOPE)
endfunction()

# Fails unless images A and B meet `strata diff --metric METRIC --threshold THRESHOLD`.
function(expect_close label a b metric threshold)
  execute_process(COMMAND ${STRATA} diff ${WORK}/${a}.png ${WORK}/${b}.png --metric ${metric}
                          --threshold ${threshold} --out ${WORK}/${a}-vs-${b}-diff.png
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(SEND_ERROR "${label}: ${a}.png against ${b}.png (difference in ${WORK}):\n${out}${err}")
  endif()
endfunction()

set(scenes horse ${MODELS}/horse.ply textured builtin:textured:4)
list(LENGTH scenes n)
math(EXPR last "${n} - 1")
foreach(i RANGE 0 ${last} 2)
  math(EXPR j "${i} + 1")
  list(GET scenes ${i} stem)
  list(GET scenes ${j} scene)
  render(${stem}-embree ${scene} embree)
  foreach(m ${methods})
    # The exact methods with room for every layer; the approximate ones with the few that fit
    # llvmpipe's 32 KB of local memory.
    set(k 8)
    if(m IN_LIST exact)
      set(k 64)
    endif()
    render(${stem}-${m}-pocl ${scene} ${m} --atomics 32 --device pthread --k ${k})
    set(pocl_fragments ${fragments})
    render(${stem}-${m}-rusticl ${scene} ${m} --device llvmpipe --k ${k})
    if(NOT fragments EQUAL pocl_fragments)
      message(SEND_ERROR "${m} on ${stem}: ${fragments} fragments on rusticl, ${pocl_fragments} on PoCL")
    endif()
    if(m IN_LIST exact OR m MATCHES "^(opaque|bdp|bdp2)$")
      # The same fragments in the same order: the same image but for float rounding.
      expect_close("${m} on ${stem}" ${stem}-${m}-rusticl ${stem}-${m}-pocl within2 0.995)
    else()
      # The approximate methods' sums and stochastic's coverage counts round differently on
      # the two compilers (stochastic: another sample pattern at a few pixels).
      expect_close("${m} on ${stem}" ${stem}-${m}-rusticl ${stem}-${m}-pocl psnr 40)
    endif()
    if(m IN_LIST exact AND NOT m STREQUAL opaque)
      expect_close("${m} on ${stem}" ${stem}-${m}-rusticl ${stem}-embree within2 0.995)
    endif()
  endforeach()
endforeach()
