# End-to-end checks of `strata pick`: a hit, a background pixel, all layers, a rectangle and JSON
# output; bad pixels and rectangles exit non-zero with a one-line "strata: error:" message.
# Run with: cmake -DSTRATA=<path to strata> -P pick_cli_test.cmake
set(failures 0)

function(expect_output name pattern)
  execute_process(COMMAND ${STRATA} ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out
                  ERROR_VARIABLE err TIMEOUT 300)
  if(NOT rc EQUAL 0)
    message(SEND_ERROR "${name}: exit ${rc}: ${err}")
  elseif(NOT out MATCHES "${pattern}")
    message(SEND_ERROR "${name}: output does not match '${pattern}':\n${out}")
  else()
    message(STATUS "${name}: ok")
  endif()
endfunction()

include(${CMAKE_CURRENT_LIST_DIR}/cli_expect.cmake)
function(expect_failure name pattern)
  expect_strata_failure(${name} "${pattern}" ${ARGN})
endfunction()

set(demo builtin:demo --size 200x150)
expect_output(hit "100,75 +object 0 \"outer sphere\"  triangle [0-9]+  depth" pick ${demo} --at 100,75)
expect_output(background "0,0 +no object \\(background\\)" pick ${demo} --at 0,0)
expect_output(all-layers "layer +object.*\n +0 +0 outer sphere.* 1\\.000000\n +1 " pick ${demo}
              --at 100,75 --all-layers)
expect_output(rect "rect 60,40,140,110: 3 objects\n  object 0 \"outer sphere\"" pick ${demo}
              --rect 60,40,140,110)
expect_output(json "\"hit\": false,[^}]*\"status\": \"background\"" pick ${demo} --at 0,0
              --at 100,75 --json)
expect_output(json-front "\"front\": {[^}]*\"name\": \"outer sphere\"" pick ${demo} --at 100,75
              --json --ortho --view 10,5)

expect_failure(outside-right "--at 200,5 is outside the 200x150 image" pick ${demo} --at 200,5)
expect_failure(outside-negative "--at -1,5 is outside" pick ${demo} --at=-1,5)
expect_failure(bad-at "--at '1,x'" pick ${demo} --at 1,x)
expect_failure(nothing "pick: nothing to pick" pick ${demo})
expect_failure(rect-reversed "--rect: rectangle 5,5,2,9" pick ${demo} --rect 5,5,2,9)
expect_failure(rect-outside "--rect: rectangle 0,0,200,9 is not inside" pick ${demo}
               --rect 0,0,200,9)
expect_failure(missing-scene "" pick /nonexistent/model.obj --at 1,1)
