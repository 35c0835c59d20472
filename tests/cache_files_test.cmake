# Cache folders keep no temporary files: an octree build interrupted by SIGTERM at any point
# leaves none (its side file included), the temporary files of processes that no longer run are
# removed when the folder is next used, and the empty files PoCL leaves in its kernel cache are
# removed once they are a minute old.
# Run with: cmake -DSTRATA=<path to strata> -DWORK=<scratch folder> -P cache_files_test.cmake
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})

# SIGTERM at 20 spread-out moments of `prep --octree` (the scene is made in about 0.7 s here and
# its octree built in about 5 s, through a temporary file and a side file): no temporary file may
# be left in the cache folder.
set(scene builtin:soup:2000000)
set(interrupted 0)
foreach(trial RANGE 1 20)
  math(EXPR delay_ms "150 + ${trial} * 250")
  set(cache ${WORK}/octree-${trial})
  execute_process(
    COMMAND sh -c "'${STRATA}' prep ${scene} --octree --cache '${cache}' >/dev/null 2>&1 & p=$!; sleep $(echo ${delay_ms} | awk '{print $1 / 1000}'); kill -TERM $p 2>/dev/null; wait $p; exit 0"
    TIMEOUT 120)
  file(GLOB left "${cache}/.*" "${cache}/*tmp*")
  if(left)
    message(SEND_ERROR "SIGTERM after ${delay_ms} ms left ${left}")
  endif()
  file(GLOB done "${cache}/*.octree")
  if(NOT done)
    math(EXPR interrupted "${interrupted} + 1")
  endif()
endforeach()
if(interrupted EQUAL 0)
  message(SEND_ERROR "every build finished before its SIGTERM: the trials tested nothing")
endif()

# Temporary files of a process that has ended (its pid is no longer running) go; a running
# process's, and any written in the last ten minutes, stay.
set(cache ${WORK}/stale)
file(MAKE_DIRECTORY ${cache})
execute_process(COMMAND sh -c "echo $$" OUTPUT_VARIABLE dead_pid OUTPUT_STRIP_TRAILING_WHITESPACE)
execute_process(COMMAND sh -c "sleep 120 >/dev/null 2>&1 & echo $!" OUTPUT_VARIABLE live_pid
                OUTPUT_STRIP_TRAILING_WHITESPACE)
file(WRITE ${cache}/.0123456789abcdef.tmp-${dead_pid}-0.octree "partial")
file(WRITE ${cache}/.0123456789abcdef.tmp-${dead_pid}-0.octree.nodes "partial")
file(WRITE ${cache}/.fedcba9876543210.tmp-${live_pid}-3.octree "in progress")
file(WRITE ${cache}/notes.txt "not strata's")
# Ten minutes without a write: a folder may be shared with other machines, whose pids mean
# nothing here, so a file still being written is never taken for an ended process's.
execute_process(COMMAND touch -d "20 minutes ago" ${cache}/.0123456789abcdef.tmp-${dead_pid}-0.octree
                        ${cache}/.0123456789abcdef.tmp-${dead_pid}-0.octree.nodes)
file(WRITE ${cache}/.0123456789abcdef.tmp-${dead_pid}-1.octree "written a moment ago")
execute_process(COMMAND ${STRATA} render builtin:demo -m octree -s 32x32 --cache ${cache}
                        -o ${WORK}/octree.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
execute_process(COMMAND kill ${live_pid})
if(NOT rc EQUAL 0)
  message(SEND_ERROR "render with a stale cache folder: exit ${rc}: ${err}")
endif()
if(EXISTS ${cache}/.0123456789abcdef.tmp-${dead_pid}-0.octree
   OR EXISTS ${cache}/.0123456789abcdef.tmp-${dead_pid}-0.octree.nodes)
  message(SEND_ERROR "the temporary files of an ended process (pid ${dead_pid}) were left")
endif()
if(NOT EXISTS ${cache}/.fedcba9876543210.tmp-${live_pid}-3.octree OR NOT EXISTS ${cache}/notes.txt
   OR NOT EXISTS ${cache}/.0123456789abcdef.tmp-${dead_pid}-1.octree)
  message(SEND_ERROR "a running process's temporary file, a fresh one or another file was removed")
endif()

# PoCL's empty temporary files: an old one goes, one with content stays. In the cache PoCL uses
# (a fresh one would make it compile every kernel again).
if(DEFINED ENV{POCL_CACHE_DIR})
  set(kcache $ENV{POCL_CACHE_DIR})
elseif(DEFINED ENV{XDG_CACHE_HOME})
  set(kcache $ENV{XDG_CACHE_HOME}/pocl/kcache)
else()
  set(kcache $ENV{HOME}/.cache/pocl/kcache)
endif()
file(MAKE_DIRECTORY ${kcache})
file(TOUCH ${kcache}/tempfile_AAAAAA)
file(WRITE ${kcache}/tempfile_BBBBBB "being written")
execute_process(COMMAND touch -d "2 hours ago" ${kcache}/tempfile_AAAAAA ${kcache}/tempfile_BBBBBB)
execute_process(COMMAND ${STRATA} render builtin:demo -s 32x32 -o ${WORK}/demo.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(SEND_ERROR "render: exit ${rc}: ${err}")
endif()
if(EXISTS ${kcache}/tempfile_AAAAAA)
  message(SEND_ERROR "an old empty PoCL temporary file was left")
endif()
if(NOT EXISTS ${kcache}/tempfile_BBBBBB)
  message(SEND_ERROR "a PoCL temporary file with content was removed")
endif()
file(REMOVE ${kcache}/tempfile_BBBBBB)

# A full disk (a 2 MB tmpfs, filled; skipped where tmpfs cannot be mounted): PoCL's cache there
# makes the kernel build fail, said in one line naming the folder; strata's own caches there
# (program binaries, cells, octree) are warnings, and the frame renders from memory.
set(small ${WORK}/small)
file(MAKE_DIRECTORY ${small})
execute_process(COMMAND mount -t tmpfs -o size=2M tmpfs ${small} RESULT_VARIABLE mounted
                ERROR_QUIET)
if(NOT mounted EQUAL 0)
  message(STATUS "full disk: tmpfs cannot be mounted here; skipped")
else()
  execute_process(COMMAND dd if=/dev/zero of=${small}/fill bs=1k count=4096 ERROR_QUIET)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=POCL_CACHE_DIR XDG_CACHE_HOME=${small}/xdg
                          ${STRATA} render builtin:demo -s 32x32 -o ${WORK}/full.png
                  RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
  string(STRIP "${err}" err)
  if(NOT rc EQUAL 1 OR NOT err MATCHES "^strata: error: building the OpenCL kernels failed on [^\n]*cache folder [^\n]* free[^\n]*$")
    message(SEND_ERROR "PoCL's cache on a full disk: exit ${rc}, '${err}'")
  endif()
  foreach(m ppll cells octree)
    execute_process(COMMAND ${CMAKE_COMMAND} -E env XDG_CACHE_HOME=${small}/xdg POCL_CACHE_DIR=${kcache}
                            ${STRATA} render builtin:demo -m ${m} -s 32x32 --cache ${small}/cache
                            -o ${WORK}/full-${m}.png
                    RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
    if(NOT rc EQUAL 0 OR NOT EXISTS ${WORK}/full-${m}.png OR NOT err MATCHES "strata: warning: ")
      message(SEND_ERROR "${m} with its caches on a full disk: exit ${rc}, '${err}'")
    endif()
  endforeach()
  file(GLOB_RECURSE left "${small}/*tmp*")
  execute_process(COMMAND umount ${small})
  if(left)
    message(SEND_ERROR "temporary files left on the full disk: ${left}")
  endif()
endif()
