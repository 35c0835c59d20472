# The command-line program where memory runs out and where a view cannot be framed, with every
# method the program lists: each case exits 1 with one "strata: error:" line (never a signal from
# inside the OpenCL driver or Embree) and leaves a good output file as it was.
# Run with: cmake -DSTRATA=<path to strata> -DWORK=<scratch folder> -P memory_limits_test.cmake
cmake_minimum_required(VERSION 3.13)  # IN_LIST
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})

include(${CMAKE_CURRENT_LIST_DIR}/cli_expect.cmake)
strata_methods(methods)

render_good_output(32x32)

# That WORK/A and WORK/B agree within 2/255 at every pixel; else an error naming WHAT.
function(expect_within_2 a b what)
  execute_process(COMMAND ${STRATA} diff ${WORK}/${a} ${WORK}/${b} --json OUTPUT_VARIABLE out)
  if(NOT out MATCHES "\"within_2\": 1.0")
    message(SEND_ERROR "${what} differ: ${out}")
  endif()
endfunction()

# Runs `command` (a shell line); expects exit 1, one "strata: error:" line matching `pattern`, and
# good.png unchanged.
function(expect_one_line name pattern command)
  execute_process(COMMAND sh -c "${command}" RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
  string(STRIP "${err}" err)
  string(REGEX MATCHALL "\n" newlines "${err}")
  list(LENGTH newlines extra_lines)
  file(SHA256 ${WORK}/good.png hash)
  if(NOT rc EQUAL 1 OR extra_lines GREATER 0 OR NOT err MATCHES "^strata: error: .*${pattern}")
    message(SEND_ERROR "${name}: exit ${rc}, message '${err}'")
  elseif(NOT hash STREQUAL good_hash)
    message(SEND_ERROR "${name}: the good output was changed")
  else()
    message(STATUS "${name}: ${err}")
  endif()
endfunction()

# A 16384x16384 frame under a 1.5 GB address space (the image alone is 1 GB): the driver never
# gets to allocate (and abort) on its own; a method that needs more than the device's largest
# allocation says so instead.
foreach(m ${methods})
  expect_one_line("${m} out of memory" "(out of memory|largest allocation)"
                  "ulimit -v 1500000; exec '${STRATA}' render builtin:demo -m ${m} -s 16384x16384 -o '${WORK}/good.png'")
endforeach()

# Under 2 GB the image fits and each method's own buffers do not (embree's fit: it renders): a
# frame or a one-line error, never a signal.
foreach(m ${methods})
  execute_process(COMMAND sh -c "ulimit -v 2000000; exec '${STRATA}' render builtin:demo -m ${m} -s 16384x16384 -o '${WORK}/big-${m}.png'"
                  RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
  string(STRIP "${err}" err)
  string(REGEX MATCHALL "\n" newlines "${err}")
  list(LENGTH newlines extra_lines)
  if(rc EQUAL 0 AND EXISTS ${WORK}/big-${m}.png)
    message(STATUS "${m} under 2 GB: rendered")
  elseif(rc EQUAL 1 AND extra_lines EQUAL 0 AND err MATCHES "^strata: error: .*(out of memory|largest allocation)")
    message(STATUS "${m} under 2 GB: ${err}")
  else()
    message(SEND_ERROR "${m} under 2 GB: exit ${rc}, message '${err}'")
  endif()
  file(REMOVE ${WORK}/big-${m}.png)
endforeach()

# A camera beyond +-1e18 (a view distance of 1e30 radii), or one whose eye rounds onto its
# target (1e-30 radii): refused by every method before any ray or vertex is computed from it.
foreach(m ${methods})
  expect_one_line("${m} unframable view" "within \\+-1e18"
                  "exec '${STRATA}' render builtin:demo -m ${m} -s 32x32 --view 30,20,1e30 -o '${WORK}/good.png'")
  expect_one_line("${m} eye on its target" "is on its target"
                  "exec '${STRATA}' render builtin:demo -m ${m} -s 32x32 --view 30,20,1e-30 -o '${WORK}/good.png'")
endforeach()

# A scene too large to frame (a triangle 1e30 across) names the file in its one line.
file(WRITE ${WORK}/huge.off "OFF\n3 1 0\n0 0 0\n1e30 0 0\n0 1e30 0\n3 0 1 2\n")
foreach(m ${methods})
  expect_one_line("${m} scene too large to frame" "huge.off: --method ${m}: the view's eye.*within \\+-1e18"
                  "exec '${STRATA}' render '${WORK}/huge.off' -m ${m} -s 32x32 -o '${WORK}/good.png'")
endforeach()

# A vertex 1e19 away that only a dropped (zero-area) triangle uses frames nothing: every method
# renders the file as it renders the same file without that vertex.
file(WRITE ${WORK}/near.off "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
file(WRITE ${WORK}/far.off "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1e19\n3 0 1 2\n3 0 1 1\n")
foreach(m ${methods})
  foreach(scene near far)
    execute_process(COMMAND ${STRATA} render ${WORK}/${scene}.off -m ${m} -s 48x48
                            -o ${WORK}/${scene}-${m}.png
                    RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
    if(NOT rc EQUAL 0)
      message(SEND_ERROR "${m} on ${scene}.off: exit ${rc}, '${err}'")
    endif()
  endforeach()
  execute_process(COMMAND ${STRATA} diff ${WORK}/near-${m}.png ${WORK}/far-${m}.png --json
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out)
  if(NOT out MATCHES "\"max_abs_error\": 0,")
    message(SEND_ERROR "${m}: the far unused vertex changed the image: ${out}")
  endif()
endforeach()

# One OBJ face of 100,000 corners that walks one triangle's loop over and over (not a whole number
# of times, so it is not read once): its fan is 33,333 coincident copies of that triangle, 33,333
# layers at every pixel it covers. Embree's all-hit merge and the octree build stay near-linear in
# the copies (they compared every pair of hits at one distance, and copied every reference into
# every node down to the deepest level: 4.4 GB), and embree's image equals ppll's.
set(corners "")
foreach(i RANGE 1 33333)
  string(APPEND corners " 1 2 3")
endforeach()
file(WRITE ${WORK}/loop-face.obj "v 0 0 0\nv 1 0 0\nv 0 1 0\nf${corners} 1\n")
foreach(m embree ppll)
  execute_process(COMMAND ${STRATA} render ${WORK}/loop-face.obj -m ${m} -s 64x64
                          -o ${WORK}/loop-face-${m}.png
                  RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
  if(NOT rc EQUAL 0)
    message(SEND_ERROR "${m} on a face of 100,000 corners: exit ${rc}, '${err}'")
  endif()
endforeach()
expect_within_2(loop-face-embree.png loop-face-ppll.png "embree and ppll on the coincident copies")
execute_process(COMMAND ${STRATA} prep ${WORK}/loop-face.obj --octree --cache ${WORK}/loop-octree --json
                OUTPUT_VARIABLE out RESULT_VARIABLE rc TIMEOUT 300)
string(REGEX MATCH "\"refs\": ([0-9]+)" refs "${out}")
if(NOT rc EQUAL 0 OR NOT CMAKE_MATCH_1 OR CMAKE_MATCH_1 GREATER 200000)
  message(SEND_ERROR "the octree of the coincident copies: exit ${rc}, ${out}")
endif()

# The octree on the same copies: one leaf the tree cannot split, 33,333 layers deep. Each tile's
# walks stop at --octree-tile-reads (its nearest layers taken, the others counted lost, with a
# warning) instead of reading the leaf once per 32 layers; the front layers already stop the
# light, so the image still equals ppll's.
execute_process(COMMAND ${STRATA} render ${WORK}/loop-face.obj -m octree -s 64x64
                        -o ${WORK}/loop-face-octree.png --cache ${WORK}/loop-octree
                        --stats ${WORK}/loop-face-octree.json
                RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
file(READ ${WORK}/loop-face-octree.json stats)
string(REGEX MATCH "\"bin_entry_reads\": ([0-9]+)" reads "${stats}")
set(reads "${CMAKE_MATCH_1}")  # the next MATCHES resets CMAKE_MATCH_1
if(NOT rc EQUAL 0 OR NOT reads OR reads GREATER 80000000 OR NOT err MATCHES
   "strata: warning: octree dropped [0-9]+ fragments in tiles whose walks reached --octree-tile-reads")
  message(SEND_ERROR "octree on a leaf of 33,333 layers: exit ${rc}, '${err}', reads ${reads}")
endif()
expect_within_2(loop-face-octree.png loop-face-ppll.png "octree and ppll on the coincident copies")
