# End-to-end checks of the command-line program's handling of bad input: each case must exit
# non-zero with a one-line "strata: error:" message, and never replace a good output file.
# Run with: cmake -DSTRATA=<path to strata> -DWORK=<scratch folder> -P cli_test.cmake
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})
set(failures 0)

function(expect_failure name)
  execute_process(COMMAND ${STRATA} ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err
                  TIMEOUT 300)
  string(STRIP "${err}" err)
  string(REGEX MATCHALL "\n" newlines "${err}")
  list(LENGTH newlines lines)
  if(rc EQUAL 0)
    message(SEND_ERROR "${name}: expected failure, got exit 0")
  elseif(NOT err MATCHES "^strata: error: ")
    message(SEND_ERROR "${name}: unexpected error text: ${err}")
  elseif(lines GREATER 0)
    message(SEND_ERROR "${name}: error message is not one line: ${err}")
  else()
    message(STATUS "${name}: exit ${rc}: ${err}")
  endif()
endfunction()

# A good output that failed commands must leave untouched.
execute_process(COMMAND ${STRATA} render builtin:demo --size 64x64 -o ${WORK}/good.png
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "rendering builtin:demo failed (exit ${rc})")
endif()
file(SHA256 ${WORK}/good.png good_hash)

expect_failure(missing-file render ${WORK}/does-not-exist.obj -o ${WORK}/good.png)
file(WRITE ${WORK}/garbage.ply "ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n")
expect_failure(malformed-ply render ${WORK}/garbage.ply -o ${WORK}/good.png)
file(WRITE ${WORK}/empty.obj "")
expect_failure(empty-obj render ${WORK}/empty.obj -o ${WORK}/good.png)
expect_failure(unknown-extension render ${WORK}/good.png -o ${WORK}/good.png)
expect_failure(unknown-method render builtin:demo --method nosuch -o ${WORK}/good.png)
expect_failure(unknown-scene render builtin:nosuch -o ${WORK}/good.png)
expect_failure(bad-layers render builtin:spheres:7 -o ${WORK}/good.png)
expect_failure(zero-size render builtin:demo --size 0x0 -o ${WORK}/good.png)
expect_failure(huge-size render builtin:demo --size 100000x100000 -o ${WORK}/good.png)
expect_failure(bad-size render builtin:demo --size large -o ${WORK}/good.png)
expect_failure(bad-view render builtin:demo --view 1,x -o ${WORK}/good.png)
expect_failure(unwritable-output render builtin:demo --size 32x32 -o /nonexistent-folder/out.png)
expect_failure(unwritable-stats render builtin:demo --size 32x32 --stats /nonexistent-folder/s.json)
expect_failure(bad-device render builtin:demo --device no-such-device -o ${WORK}/good.png)
expect_failure(diff-missing diff ${WORK}/good.png ${WORK}/nothing.png)
if(EXISTS /usr/share/assimp/models/glTF2/IndexOutOfRange/IndexOutOfRange.gltf)
  expect_failure(gltf-missing-bin render /usr/share/assimp/models/glTF2/MissingBin/BoxTextured.gltf
                 -o ${WORK}/good.png)
endif()

file(SHA256 ${WORK}/good.png after_hash)
if(NOT good_hash STREQUAL after_hash)
  message(SEND_ERROR "a failed command changed the existing output good.png")
endif()
file(GLOB leftovers ${WORK}/.*tmp* ${WORK}/*.tmp*)
if(leftovers)
  message(SEND_ERROR "temporary files left behind: ${leftovers}")
endif()

# Stats JSON carries the documented fields.
execute_process(COMMAND ${STRATA} render builtin:demo --size 64x64 --method ppll --frames 2
                        --stats ${WORK}/stats.json RESULT_VARIABLE rc)
file(READ ${WORK}/stats.json stats)
foreach(field method scene width height device triangles triangles_read fragments
              max_depth_complexity device_bytes fragment_bytes kernel_launches frame_ms stage_ms)
  string(JSON value ERROR_VARIABLE jerr GET "${stats}" ${field})
  if(jerr)
    message(SEND_ERROR "stats.json lacks ${field}")
  endif()
endforeach()
string(JSON runs GET "${stats}" frame_ms runs)
if(NOT runs EQUAL 2)
  message(SEND_ERROR "stats.json frame_ms.runs is ${runs}, expected 2")
endif()
