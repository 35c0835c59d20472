# Distributed rendering under mpirun: for P = 1, 2, 3, 4 and 7 processes the composited image
# equals the single-process octree image within 1/255 with the same fragment count, from views
# outside, inside and orthographic, transparency and translucency; each rank reads only its own
# leaves (its disk reads are its references, and the references of all ranks add up to the
# scene's); a rank that fails, is stopped or is killed makes the job exit non-zero with one line
# naming it, without hanging; the scaling bench runs.
# Run with: cmake -DSTRATA=<strata> -DMPIRUN=<mpirun> -DWORK=<scratch> -P distributed_test.cmake
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})
# CI runs as root on 2 cores: Open MPI needs leave for both.
set(ENV{OMPI_ALLOW_RUN_AS_ROOT} 1)
set(ENV{OMPI_ALLOW_RUN_AS_ROOT_CONFIRM} 1)
set(ENV{OMPI_MCA_btl_vader_single_copy_mechanism} none)
set(MPI ${MPIRUN} --oversubscribe --bind-to none)

function(run_checked what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err
                  TIMEOUT 300)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} failed (exit ${rc}):\n${out}\n${err}")
  endif()
endfunction()

# The octree scenes: a city (coplanar walls, dangling triangles), triangle soup and a scan.
run_checked("prep city" ${STRATA} prep builtin:city:6 --octree --leaf-tris 1500
            --cache ${WORK}/cache -o ${WORK}/city.octree)
run_checked("prep soup" ${STRATA} prep builtin:soup:20000 --octree --leaf-tris 1500
            --cache ${WORK}/cache -o ${WORK}/soup.octree)
run_checked("prep shells" ${STRATA} prep builtin:shells:3 --octree --leaf-tris 2000
            --cache ${WORK}/cache -o ${WORK}/shells.octree)
run_checked("prep horse" ${STRATA} prep ${MODELS}/horse.ply --octree --leaf-tris 3000
            --cache ${WORK}/cache -o ${WORK}/horse.octree)

set(checked 0)
# compare(NAME SCENE P VIEW...): the distributed and the single-process image and statistics.
function(compare name scene processes)
  set(common ${WORK}/${scene}.octree -s 96x80 ${ARGN})
  run_checked("${name}: single process" ${STRATA} render ${common} -m octree
              -o ${WORK}/${name}-single.png --stats ${WORK}/${name}-single.json)
  run_checked("${name}: ${processes} processes" ${MPI} -np ${processes} ${STRATA} render ${common}
              --distributed -o ${WORK}/${name}-mpi.png --stats ${WORK}/${name}-mpi.json)
  execute_process(COMMAND ${STRATA} diff ${WORK}/${name}-single.png ${WORK}/${name}-mpi.png
                          --json --out ${WORK}/${name}-diff.png
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out)
  string(JSON max_err ERROR_VARIABLE jerr GET "${out}" max_abs_error)
  if(NOT rc EQUAL 0 OR jerr OR max_err GREATER 1)
    message(SEND_ERROR "${name}: the composited image differs by ${max_err}/255 (images and "
                       "difference in ${WORK}): ${out}")
  endif()
  file(READ ${WORK}/${name}-single.json single)
  file(READ ${WORK}/${name}-mpi.json mpi)
  string(JSON single_fragments GET "${single}" fragments)
  string(JSON mpi_fragments GET "${mpi}" fragments)
  string(JSON single_depth GET "${single}" max_depth_complexity)
  string(JSON mpi_depth GET "${mpi}" max_depth_complexity)
  if(NOT single_fragments EQUAL mpi_fragments OR NOT single_depth EQUAL mpi_depth)
    message(SEND_ERROR "${name}: fragments ${mpi_fragments} (deepest ${mpi_depth}) over the "
                       "ranks, ${single_fragments} (${single_depth}) in one process")
  endif()
  string(JSON refs GET "${single}" octree_refs)
  string(JSON ranks LENGTH "${mpi}" ranks)
  if(NOT ranks EQUAL processes)
    message(SEND_ERROR "${name}: ${ranks} ranks reported, ${processes} expected")
  endif()
  set(sum 0)
  math(EXPR last "${ranks} - 1")
  foreach(r RANGE ${last})
    string(JSON rank_refs GET "${mpi}" ranks ${r} triangle_refs)
    string(JSON rank_read GET "${mpi}" ranks ${r} disk_read_bytes)
    math(EXPR own "${rank_refs} * 44")
    if(NOT rank_read EQUAL own)
      message(SEND_ERROR "${name}: rank ${r} read ${rank_read} bytes, its own leaves are ${own}")
    endif()
    math(EXPR sum "${sum} + ${rank_refs}")
  endforeach()
  if(NOT sum EQUAL refs)
    message(SEND_ERROR "${name}: the ranks' references add up to ${sum}, the scene has ${refs}")
  endif()
  message(STATUS "${name}: ${processes} processes, max error ${max_err}/255, ${mpi_fragments} "
                 "fragments")
endfunction()

foreach(p 1 2 3 4 7)
  compare(city-p${p} city ${p} --view 35,30)
endforeach()
compare(city-inside city 3 --view 200,15,0.3)
compare(city-ortho city 4 --view 80,60 --ortho)
compare(city-under city 7 --view 10,-70 --alpha 0.3)
compare(soup-p3 soup 3 --view 20,25)
compare(soup-ortho soup 2 --view 120,10 --ortho)
compare(horse-p4 horse 4 --view 60,10)
compare(horse-budget horse 3 --view 300,20 --memory-budget 2)
# Translucency: shells cut by the boxes' faces (the inside count and the absorption carried
# from box to box), the city's open walls (back faces met outside every shell), from inside.
foreach(p 2 3 4)
  compare(shells-translucent-p${p} shells ${p} --view 120,15 --effect translucency)
endforeach()
compare(shells-translucent-inside shells 3 --view 40,30,0.2 --effect translucency)
compare(shells-translucent-ortho shells 4 --view 200,-20 --ortho --effect translucency)
compare(city-translucent city 7 --view 120,15 --effect translucency)
compare(city-translucent-inside city 3 --view 200,15,0.3 --effect translucency --sigma 0.5)

# A mesh scene: rank 0 writes its octree scene into the cache first.
run_checked("mesh scene" ${MPI} -np 2 ${STRATA} render builtin:shells:2 --distributed -s 64x64
            --cache ${WORK}/cache -o ${WORK}/shells-mpi.png)
run_checked("mesh scene, single" ${STRATA} render builtin:shells:2 -m octree -s 64x64
            --cache ${WORK}/cache -o ${WORK}/shells-single.png)
execute_process(COMMAND ${STRATA} diff ${WORK}/shells-single.png ${WORK}/shells-mpi.png --json
                OUTPUT_VARIABLE out)
string(JSON max_err GET "${out}" max_abs_error)
if(max_err GREATER 1)
  message(SEND_ERROR "shells: the composited image differs by ${max_err}/255")
endif()

# Faults: one line from rank 0 naming the failing rank, a non-zero exit, no hang.
function(expect_job_failure name expect)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err
                  TIMEOUT 120)
  # Counted by their prefix: a message may hold semicolons, CMake's list separator.
  string(REGEX MATCHALL "strata: error:" prefixes "${err}")
  list(LENGTH prefixes count)
  string(REGEX MATCH "strata: error: [^\n]*" lines "${err}")
  if(rc EQUAL 0 OR rc MATCHES "timeout")
    message(SEND_ERROR "${name}: expected a failure, got '${rc}'")
  elseif(NOT count EQUAL 1 OR NOT err MATCHES "${expect}")
    message(SEND_ERROR "${name}: expected one 'strata: error:' line matching '${expect}': ${err}")
  else()
    message(STATUS "${name}: ${lines}")
  endif()
endfunction()
expect_job_failure(failing-rank "rank 1: failed on purpose"
                   ${MPI} -np 3 ${STRATA} render ${WORK}/city.octree --distributed -s 64x64
                   --fail-rank 1 -o ${WORK}/fail.png)
# A rank failing on its own outside the checked steps (the others already waiting in the
# composite): it names itself and the job ends, instead of waiting for ever.
expect_job_failure(failing-rank-late "rank 1: failed on purpose"
                   ${MPI} -np 3 ${STRATA} render ${WORK}/city.octree --distributed -s 64x64
                   --fail-rank-late 1 -o ${WORK}/fail.png)
expect_job_failure(missing-scene "rank 0: .*nothing.octree"
                   ${MPI} -np 2 ${STRATA} render ${WORK}/nothing.octree --distributed -s 64x64)
expect_job_failure(other-method "octree method"
                   ${MPI} -np 2 ${STRATA} render ${WORK}/city.octree --distributed -m ppll)
# Ranks started with different options (Open MPI's MPMD form, A : B) all stop at the first
# collective with one line naming the first rank and option that differ, whatever differs: the
# image size (which sized the compositing collectives), the frames (which counted them), the effect.
expect_job_failure(other-size "rank 2 was started with another --size than rank 0"
                   ${MPI} -np 2 ${STRATA} render ${WORK}/city.octree --distributed -s 64x64
                   -o ${WORK}/fail.png : -np 1 ${STRATA} render ${WORK}/city.octree --distributed
                   -s 128x128 -o ${WORK}/fail.png)
expect_job_failure(other-frames "rank 1 was started with another --frames than rank 0"
                   ${MPI} -np 1 ${STRATA} render ${WORK}/city.octree --distributed -s 64x64
                   --frames 2 -o ${WORK}/fail.png : -np 1 ${STRATA} render ${WORK}/city.octree
                   --distributed -s 64x64 --frames 3 -o ${WORK}/fail.png)
expect_job_failure(other-effect "rank 1 was started with another --effect than rank 0"
                   ${MPI} -np 1 ${STRATA} render ${WORK}/shells.octree --distributed -s 64x64
                   -o ${WORK}/fail.png : -np 1 ${STRATA} render ${WORK}/shells.octree
                   --distributed -s 64x64 --effect translucency -o ${WORK}/fail.png)
# A rank stopped (SIGSTOP) while the others wait for it: every live rank exits within the rank
# timeout, the lowest of them printing one line naming it (rank 0 itself stopped: rank 1 says
# so). A rank killed: the launcher ends the job, and the lowest survivor names the lost rank.
# The ranks render 2,000 frames of their shares, which outlasts the delay before the signal.
function(expect_signalled name signal rank expect)
  string(TIMESTAMP t0 "%s")
  expect_job_failure(${name} "${expect}" sh ${CMAKE_CURRENT_LIST_DIR}/signal_rank.sh ${signal}
                     ${rank} 1.5 ${MPI} -np 3 ${STRATA} render ${WORK}/city.octree --distributed
                     -s 128x128 --frames 2000 --rank-timeout 3 -o ${WORK}/fail.png)
  string(TIMESTAMP t1 "%s")
  math(EXPR took "${t1} - ${t0}")
  message(STATUS "${name}: ended after ${took} s")
endfunction()
expect_signalled(stopped-rank STOP 1 "rank 1 stopped answering .*rank 0 waited [0-9]+ s")
expect_signalled(stopped-rank-0 STOP 0 "rank 0 stopped answering .*rank 1 waited [0-9]+ s")
expect_signalled(killed-rank KILL 2 "rank 2 was lost")
if(EXISTS ${WORK}/fail.png)
  message(SEND_ERROR "a failed job wrote its image")
endif()

# The scaling table: runs, writes its results, and every image matches one process's.
run_checked("bench --distributed" ${STRATA} bench --distributed --scenes builtin:soup:3000
            --processes 1,2,3 --size 64x48 --frames 1 --out ${WORK}/bench)
file(READ ${WORK}/bench/results.json results)
string(JSON rows LENGTH "${results}")
if(NOT rows EQUAL 3)
  message(SEND_ERROR "bench --distributed wrote ${rows} rows, 3 expected")
endif()
foreach(i 0 1 2)
  string(JSON err GET "${results}" ${i} bench max_error_vs_first)
  if(err GREATER 1)
    message(SEND_ERROR "bench --distributed: row ${i} differs from one process by ${err}/255")
  endif()
endforeach()
if(NOT EXISTS ${WORK}/bench/results.md)
  message(SEND_ERROR "bench --distributed wrote no results.md")
endif()
