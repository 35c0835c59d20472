# What the command-line tests (cmake -P scripts) share: the methods the program lists, a command
# that must fail with one "strata: error:" line, and a good output file that failed commands must
# leave as it was.

# Runs `strata ARGN`; expects a non-zero exit and stderr one line "strata: error: PATTERN...".
function(expect_strata_failure name pattern)
  execute_process(COMMAND ${STRATA} ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out
                  ERROR_VARIABLE err TIMEOUT 300)
  string(STRIP "${err}" err)
  string(REGEX MATCHALL "\n" newlines "${err}")
  list(LENGTH newlines lines)
  if(rc EQUAL 0)
    message(SEND_ERROR "${name}: expected failure, got exit 0")
  elseif(NOT err MATCHES "^strata: error: ${pattern}")
    message(SEND_ERROR "${name}: unexpected error text: ${err}")
  elseif(lines GREATER 0)
    message(SEND_ERROR "${name}: error message is not one line: ${err}")
  else()
    message(STATUS "${name}: exit ${rc}: ${err}")
  endif()
endfunction()

# Renders builtin:demo at SIZE into WORK/good.png and sets good_hash (in the caller) to its hash.
function(render_good_output size)
  execute_process(COMMAND ${STRATA} render builtin:demo --size ${size} -o ${WORK}/good.png
                  RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "rendering builtin:demo failed (exit ${rc})")
  endif()
  file(SHA256 ${WORK}/good.png hash)
  set(good_hash ${hash} PARENT_SCOPE)
endfunction()

# Sets `out` (in the caller) to every method `strata render --help` lists (its lines
# "    NAME: summary" under --method), in the registry's order.
cmake_policy(PUSH)
cmake_policy(SET CMP0057 NEW)  # IN_LIST, also where the including script sets no version
function(strata_methods out)
  execute_process(COMMAND ${STRATA} render --help OUTPUT_VARIABLE help RESULT_VARIABLE rc)
  string(REGEX MATCHALL "\n +([a-z0-9]+): " lines "${help}")
  set(methods "")
  foreach(line ${lines})
    string(REGEX REPLACE "\n +([a-z0-9]+): " "\\1" name "${line}")
    list(APPEND methods ${name})
  endforeach()
  list(REMOVE_DUPLICATES methods)
  list(LENGTH methods count)
  if(NOT rc EQUAL 0 OR count LESS 10 OR NOT "cells" IN_LIST methods OR NOT "embree" IN_LIST methods)
    message(FATAL_ERROR "could not read the methods from render --help: '${methods}'")
  endif()
  set(${out} ${methods} PARENT_SCOPE)
endfunction()
cmake_policy(POP)
