# Every OpenCL method under the Oclgrind simulator, with the limits of a modest GPU: every memory
# access checked, data races, API misuse and (for the methods it can follow) uses of
# uninitialised values reported, and the process must exit 0 (no crash at exit either). Fails on
# any error in Oclgrind's log.
cmake_minimum_required(VERSION 3.13)  # IN_LIST
file(MAKE_DIRECTORY ${WORK})
# Every OpenCL method the program lists (embree runs on the CPU, without OpenCL).
include(${CMAKE_CURRENT_LIST_DIR}/cli_expect.cmake)
strata_methods(methods)
list(REMOVE_ITEM methods embree)

# Oclgrind 21.10's uninitialised-value checker loses what dp and ddp store into their
# accumulators (a constant stored and read back is reported uninitialised), so those two run
# without it. It needs -fpreserve-vec3-type (kernels/common.cl says why). Both kinds of run share
# one program cache, so a program built without that option must not be taken for one built with
# it (the cache key includes Oclgrind's build options).
set(plain_methods dp ddp)

# `strata render ARGN -o WORK/OUTPUT` under Oclgrind with the options in the list CHECKS; fails,
# naming LABEL, on a non-zero exit or anything in Oclgrind's log.
function(render_under_oclgrind label checks output)
  set(log ${WORK}/${label}.log)
  file(REMOVE ${log})
  set(cache ${WORK}/cache)
  execute_process(
    COMMAND ${CMAKE_COMMAND} -E env XDG_CACHE_HOME=${cache}
            ${OCLGRIND} ${checks} --data-races --check-api --max-wgsize 256
            --local-mem-size 49152 --log ${log} ${STRATA} render ${ARGN} -o ${WORK}/${output}
    RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  set(text "")
  if(EXISTS ${log})
    file(READ ${log} text)
  endif()
  string(STRIP "${text}" text)
  if(NOT rc EQUAL 0 OR NOT text STREQUAL "")
    message(FATAL_ERROR "${label} under oclgrind: exit ${rc}\n${out}\n${err}\n${text}")
  endif()
endfunction()

set(uninitialized --uninitialized --build-options -fpreserve-vec3-type)

# Every method on SCENE, each in its own process (Oclgrind's log keeps only the last OpenCL
# context's reports, and a render of several methods may make several) and under the checks it
# can take, into WORK/STEM-METHOD.png.
# The checks method M can take, into `out`: all of them, or without the uninitialised-value
# checker for the plain methods.
function(checks_for m out)
  set(checks "${uninitialized}")
  if(m IN_LIST plain_methods)
    set(checks "")
  endif()
  set(${out} "${checks}" PARENT_SCOPE)
endfunction()

function(render_every_method label stem scene)
  foreach(m ${methods})
    checks_for(${m} checks)
    render_under_oclgrind(${label}-${m} "${checks}" ${stem}-${m}.png ${scene} --method ${m}
                          ${ARGN})
  endforeach()
endfunction()

render_every_method(demo oclgrind builtin:demo --size 32x32)
foreach(m ${methods})
  if(NOT EXISTS ${WORK}/oclgrind-${m}.png)
    message(FATAL_ERROR "no image from ${m} under oclgrind")
  endif()
endforeach()

# A shared mesh, a textured scene and a triangle soup with degenerate triangles (slots setup
# leaves empty, whose records nothing may read), every method, each image identical to PoCL's:
# a missing barrier or a racy local update that PoCL's one-item-after-another execution hides
# would show here as a different image even where Oclgrind's own checks stay quiet.
foreach(case "teapot;${MODELS}/teapot.obj" "textured;builtin:textured:4" "soup;builtin:soup:300")
  list(GET case 0 name)
  list(GET case 1 scene)
  render_every_method(${name} ${name}-oclgrind ${scene} --size 32x32)
  execute_process(COMMAND ${STRATA} render ${scene} --method all --size 32x32
                          -o ${WORK}/${name}-pocl.png
                  RESULT_VARIABLE rc OUTPUT_QUIET)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name} on the default device: exit ${rc}")
  endif()
  foreach(m ${methods})
    file(SHA256 ${WORK}/${name}-oclgrind-${m}.png simulated)
    file(SHA256 ${WORK}/${name}-pocl-${m}.png native)
    if(NOT simulated STREQUAL native)
      message(FATAL_ERROR "${name} ${m}: the image under oclgrind differs from the default "
                          "device's (${WORK}/${name}-oclgrind-${m}.png, ${name}-pocl-${m}.png)")
    endif()
  endforeach()
endforeach()

# The serial forms of the tile kernels (a work-item alone per tile: what PoCL's CPU devices run
# by default, while Oclgrind's default is the work-group form) under the same checks, on the
# teapot; each image identical to PoCL's.
foreach(m ${methods})
  checks_for(${m} checks)
  render_under_oclgrind(teapot-serial-${m} "${checks}" teapot-serial-${m}.png
                        ${MODELS}/teapot.obj --method ${m} --size 32x32 --tile-kernels serial)
  file(SHA256 ${WORK}/teapot-serial-${m}.png simulated)
  file(SHA256 ${WORK}/teapot-pocl-${m}.png native)
  if(NOT simulated STREQUAL native)
    message(FATAL_ERROR "teapot ${m}: the serial tile kernels' image under oclgrind differs from "
                        "the default device's (${WORK}/teapot-serial-${m}.png, teapot-pocl-${m}.png)")
  endif()
endforeach()

# The octree method on a scene of many leaves that share triangles, with a 2-fragment k-buffer,
# so tiles take several walks per leaf (the demo fits one leaf); then the same with the early out
# at opacity 0.9, so tiles saturate and skip leaves.
set(shells builtin:shells:2 --method octree --leaf-tris 1500 --octree-k 2 --size 24x24
           --cache ${WORK}/octree-cache)
render_under_oclgrind(octree "${uninitialized}" oclgrind-shells.png ${shells})
render_under_oclgrind(octree-early-out "${uninitialized}" oclgrind-shells-early.png ${shells}
                      --octree-early-out
                      --alpha 0.9)
# The same with a tile bound of 150 reads, so leaves stop early and count what they leave: the
# k-buffer variant, depth peeling's (whose count is one more walk) and the serial kernel form.
foreach(case "bound;kbuffer;group" "bound-dp;dp;group" "bound-serial;blocks;serial")
  list(GET case 0 name)
  list(GET case 1 variant)
  list(GET case 2 kernels)
  render_under_oclgrind(octree-${name} "${uninitialized}" oclgrind-shells-${name}.png ${shells}
                        --octree-tile-reads 150 --octree-variant ${variant}
                        --tile-kernels ${kernels} --stats ${WORK}/octree-${name}.json)
  file(READ ${WORK}/octree-${name}.json stats)
  if(NOT stats MATCHES "\"fragments_lost\": *[1-9]")
    message(FATAL_ERROR "octree ${variant} under oclgrind: the tile bound dropped nothing "
                        "(${WORK}/octree-${name}.json)")
  endif()
endforeach()
foreach(image oclgrind-shells.png oclgrind-shells-early.png oclgrind-shells-bound.png
              oclgrind-shells-bound-dp.png oclgrind-shells-bound-serial.png)
  if(NOT EXISTS ${WORK}/${image})
    message(FATAL_ERROR "no image ${image} from the octree method under oclgrind")
  endif()
endforeach()

# The cells order's pixel masks and pairs on the device (cells_order_masks.cl,
# cells_order_pairs.cl) over a moving camera, each
# frame ordering its own view (no order made ahead under Oclgrind), the image identical to
# PoCL's (host masks there: the same bits, so the same order).
render_under_oclgrind(cells-order-masks "${uninitialized}" oclgrind-masks.png ${MODELS}/horse.ply
                      --method cells --size 40x40 --frames 2 --orbit 10 --order-masks device
                      --stats ${WORK}/oclgrind-masks.json)
file(READ ${WORK}/oclgrind-masks.json stats)
if(NOT stats MATCHES "\"order_device_cells\": *[1-9]")
  message(FATAL_ERROR "cells under oclgrind: no masks were made on the device (${WORK}/oclgrind-masks.json)")
endif()
execute_process(COMMAND ${STRATA} render ${MODELS}/horse.ply --method cells --size 40x40 --frames 2
                        --orbit 10 --order-masks host -o ${WORK}/pocl-masks.png
                RESULT_VARIABLE rc OUTPUT_QUIET)
file(SHA256 ${WORK}/oclgrind-masks.png simulated)
file(SHA256 ${WORK}/pocl-masks.png native)
if(NOT rc EQUAL 0 OR NOT simulated STREQUAL native)
  message(FATAL_ERROR "cells with the order's masks on the device under oclgrind: exit ${rc}, or "
                      "an image that differs from PoCL's (${WORK}/oclgrind-masks.png, pocl-masks.png)")
endif()

# A device too small for the frame: the buffers alive together are counted against its memory,
# so the error is one line naming what did not fit (not a crash, and not only per buffer).
execute_process(
  COMMAND ${OCLGRIND} --global-mem-size 600000 ${STRATA} render builtin:demo --method ppll
          --size 32x32 -o ${WORK}/oclgrind-small.png
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 300)
string(STRIP "${err}" err)
if(NOT rc EQUAL 1 OR NOT err MATCHES "^strata: error: [^\n]*: device .* is out of memory: [0-9]+ bytes for [a-z ]+ with [0-9]+ bytes already in use")
  message(FATAL_ERROR "a 600 KB device: exit ${rc}, message '${err}'")
endif()
