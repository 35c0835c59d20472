# End-to-end checks of the command-line program's handling of bad input: each case must exit
# non-zero with a one-line "strata: error:" message, and never replace a good output file.
# Run with: cmake -DSTRATA=<path to strata> -DWORK=<scratch folder> -P cli_test.cmake
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})
set(failures 0)

include(${CMAKE_CURRENT_LIST_DIR}/cli_expect.cmake)
function(expect_failure name)
  expect_strata_failure(${name} "" ${ARGN})
endfunction()

# A good output that failed commands must leave untouched.
render_good_output(64x64)

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
expect_failure(bad-alpha render builtin:demo --alpha -0.5 -o ${WORK}/good.png)
expect_failure(bad-k render builtin:demo --method abuffer --k 0 -o ${WORK}/good.png)
expect_failure(bad-cells-batch render builtin:demo --method cells --cells-batch 0 -o ${WORK}/good.png)
expect_failure(bad-suite bench --suite nosuch --out ${WORK}/bench)
expect_failure(unwritable-output render builtin:demo --size 32x32 -o /nonexistent-folder/out.png)
expect_failure(unwritable-stats render builtin:demo --size 32x32 --stats /nonexistent-folder/s.json)
expect_failure(bad-device render builtin:demo --device no-such-device -o ${WORK}/good.png)
expect_failure(diff-missing diff ${WORK}/good.png ${WORK}/nothing.png)
# A truncated PNG, compared and used as a texture: strata's line alone (libpng, left to itself,
# prints a second one).
execute_process(COMMAND head -c 300 ${WORK}/good.png OUTPUT_FILE ${WORK}/truncated.png)
expect_failure(diff-truncated-png diff ${WORK}/good.png ${WORK}/truncated.png)
# A gate on one metric: an image against itself passes any bound; against an approximation it
# misses a tight one with exit 3 and one line naming the metric, and passes a loose one.
execute_process(COMMAND ${STRATA} diff ${WORK}/good.png ${WORK}/good.png --metric max --threshold 0
                RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(SEND_ERROR "diff of an image with itself missed --metric max --threshold 0 (exit ${rc})")
endif()
execute_process(COMMAND ${STRATA} render builtin:demo -m wboit --size 64x64 -o ${WORK}/wboit.png
                RESULT_VARIABLE rc)
foreach(gate "psnr;60;3" "psnr;20;0" "rmse;0.5;3" "within2;0.999;3" "mean;50;0" "ssim;0.9999;3"
             "ssim;0.5;0")
  list(GET gate 0 metric)
  list(GET gate 1 bound)
  list(GET gate 2 expected)
  execute_process(COMMAND ${STRATA} diff ${WORK}/good.png ${WORK}/wboit.png --metric ${metric}
                          --threshold ${bound} RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
  string(STRIP "${err}" err)
  if(NOT rc EQUAL expected)
    message(SEND_ERROR "diff --metric ${metric} --threshold ${bound}: exit ${rc}, not ${expected}")
  elseif(expected EQUAL 3 AND NOT err MATCHES "^strata diff: .*: ${metric} [0-9.e+-]+ is (below|above) the threshold [0-9.e+-]+$")
    message(SEND_ERROR "diff --metric ${metric}: unexpected message: ${err}")
  endif()
endforeach()
expect_failure(diff-unknown-metric diff ${WORK}/good.png ${WORK}/good.png --metric ssimx --threshold 1)
expect_failure(diff-metric-without-threshold diff ${WORK}/good.png ${WORK}/good.png --metric psnr)
# SSIM needs 11 pixels a side: a smaller image prints n/a, and a gate on it is an error.
execute_process(COMMAND ${STRATA} render builtin:demo --size 8x8 -o ${WORK}/tiny.png RESULT_VARIABLE rc)
execute_process(COMMAND ${STRATA} diff ${WORK}/tiny.png ${WORK}/tiny.png RESULT_VARIABLE rc
                OUTPUT_VARIABLE out)
if(NOT rc EQUAL 0 OR NOT out MATCHES "ssim +n/a")
  message(SEND_ERROR "diff of 8x8 images: exit ${rc}, output ${out}")
endif()
expect_failure(diff-ssim-tiny diff ${WORK}/tiny.png ${WORK}/tiny.png --metric ssim --threshold 0.5)
file(WRITE ${WORK}/textured.obj "mtllib textured.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl t\nf 1/1 2/2 3/3\n")
file(WRITE ${WORK}/textured.mtl "newmtl t\nmap_Kd truncated.png\n")
expect_failure(truncated-texture render ${WORK}/textured.obj --size 32x32 -o ${WORK}/good.png)
# The convex-cells method and its preprocessing.
expect_failure(bad-decompose render builtin:demo --method cells --decompose loose -o ${WORK}/good.png)
expect_failure(bad-effect render builtin:demo --method cells --effect glow -o ${WORK}/good.png)
expect_failure(translucency-unsupported render builtin:demo --method ppll --effect translucency -o ${WORK}/good.png)
expect_failure(bad-sigma render builtin:demo --method cells --effect translucency --sigma -1 -o ${WORK}/good.png)
expect_failure(prep-missing prep ${WORK}/does-not-exist.obj --cache ${WORK}/cells)
expect_failure(prep-many-meshes prep builtin:demo --cache ${WORK}/cells -o ${WORK}/demo.cells)
expect_failure(prep-unwritable prep builtin:spheres:16 --cache ${WORK}/cells -o /nonexistent-folder/x.cells)
expect_failure(prep-export-unwritable prep builtin:spheres:16 --cache ${WORK}/cells --export /nonexistent-folder/x.ply)
expect_failure(prep-export-not-ply prep builtin:spheres:16 --cache ${WORK}/cells --export ${WORK}/cells.obj)
# The octree build.
expect_failure(octree-leaf-zero prep builtin:demo --octree --leaf-tris 0 --cache ${WORK}/octree)
expect_failure(octree-export prep builtin:demo --octree --export ${WORK}/o.ply --cache ${WORK}/octree)
expect_failure(octree-render-leaf-zero render builtin:demo -m octree --leaf-tris 0 --size 16x16 --cache ${WORK}/octree)
expect_failure(octree-render-variant render builtin:demo -m octree --octree-variant fastest --size 16x16 --cache ${WORK}/octree)
expect_failure(octree-render-k render builtin:demo -m octree --octree-k 65 --size 16x16 --cache ${WORK}/octree)
expect_failure(octree-unwritable prep builtin:demo --octree --cache ${WORK}/octree -o /nonexistent-folder/x.octree)
execute_process(COMMAND ${STRATA} prep builtin:demo --octree --leaf-tris 64 --cache ${WORK}/octree
                        -o ${WORK}/demo.octree --json
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
string(JSON leaves ERROR_VARIABLE jerr GET "${out}" leaves)
if(NOT rc EQUAL 0 OR jerr OR leaves LESS 2 OR NOT EXISTS ${WORK}/demo.octree)
  message(SEND_ERROR "prep --octree failed (exit ${rc}): ${err} ${out}")
endif()
# --cells-batch cuts a cells frame into batches, and the stats say how many.
execute_process(COMMAND ${STRATA} render builtin:soup:300 -m cells --size 48x48 --cells-batch 100
                        -o ${WORK}/cells-batches.png --stats ${WORK}/cells-batches.json
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(SEND_ERROR "render with --cells-batch failed (exit ${rc}): ${err} ${out}")
else()
  file(READ ${WORK}/cells-batches.json stats)
  string(JSON batches GET "${stats}" batches)
  if(batches LESS 2)
    message(SEND_ERROR "--cells-batch 100 drew builtin:soup:300 in ${batches} batch(es)")
  endif()
endif()
# The octree scene (prep --octree -o FILE.octree), rendered out of core from it.
expect_failure(octree-scene-extension prep builtin:demo --octree --cache ${WORK}/octree -o ${WORK}/demo.bin)
expect_failure(octree-scene-textured prep builtin:textured:2 --octree --cache ${WORK}/octree -o ${WORK}/tex.octree)
execute_process(COMMAND ${STRATA} render ${WORK}/demo.octree -m octree,ppll --size 48x48
                        --memory-budget 2 -o ${WORK}/ooc.png --stats ${WORK}/ooc.json
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT EXISTS ${WORK}/ooc-octree.png OR NOT EXISTS ${WORK}/ooc-ppll.png)
  message(SEND_ERROR "render of an octree scene failed (exit ${rc}): ${err} ${out}")
else()
  file(READ ${WORK}/ooc.json stats)
  string(JSON source GET "${stats}" 0 stream_source)
  if(NOT source STREQUAL "disk")
    message(SEND_ERROR "the octree scene was not streamed from disk: '${source}'")
  endif()
endif()
execute_process(COMMAND ${STRATA} render builtin:demo -m octree --size 48x48 -o ${WORK}/mem.png
                RESULT_VARIABLE rc)
execute_process(COMMAND ${STRATA} diff ${WORK}/mem.png ${WORK}/ooc-octree.png --json
                RESULT_VARIABLE rc OUTPUT_VARIABLE out)
string(JSON max_err ERROR_VARIABLE jerr GET "${out}" max_abs_error)
if(NOT rc EQUAL 0 OR jerr OR max_err GREATER 1)
  message(SEND_ERROR "the octree scene renders otherwise than its scene: ${out}")
endif()
# The first 4000 bytes: a head and leaves without the index.
execute_process(COMMAND head -c 4000 ${WORK}/demo.octree OUTPUT_FILE ${WORK}/half.octree)
expect_failure(octree-scene-truncated render ${WORK}/half.octree -m octree -o ${WORK}/good.png)
expect_failure(octree-scene-truncated-ppll render ${WORK}/half.octree -m ppll -o ${WORK}/good.png)
execute_process(COMMAND mkfifo ${WORK}/fifo.octree)
expect_failure(octree-scene-fifo render ${WORK}/fifo.octree -m octree -o ${WORK}/good.png)
expect_failure(octree-scene-dp render ${WORK}/demo.octree -m octree --octree-variant dp -o ${WORK}/good.png)
# Coordinates beyond what Embree can trace: the reference refuses rather than lose them.
file(WRITE ${WORK}/huge.off "OFF\n3 1 0\n0 0 0\n5e18 0 0\n0 5e18 0\n3 0 1 2\n")
expect_failure(embree-huge-coordinates render ${WORK}/huge.off -m embree -s 32x32 -o ${WORK}/good.png)
# Command-line parse errors: one line with the prefix too.
expect_failure(parse-unknown-option render builtin:demo --no-such-option -o ${WORK}/good.png)
expect_failure(parse-bad-number render builtin:demo --frames many -o ${WORK}/good.png)
expect_failure(parse-no-command)
# Option values: a bad hex colour, colours outside 0..1, frame counts out of range, and diff on
# a FIFO (which would block).
expect_failure(background-hex render builtin:demo --background "#12zz56" -o ${WORK}/good.png)
expect_failure(background-short render builtin:demo --background "#123" -o ${WORK}/good.png)
expect_failure(background-range render builtin:demo --background 1e38,-5,2 -o ${WORK}/good.png)
expect_failure(frames-huge render builtin:demo --frames 1000000000 -o ${WORK}/good.png)
expect_failure(bench-frames-zero bench --suite smoke --frames 0 --out ${WORK}/bench)
expect_failure(orbit-range render builtin:demo --orbit 400 -o ${WORK}/good.png)
expect_failure(orbit-nan render builtin:demo --orbit nan -o ${WORK}/good.png)
expect_failure(orbit-word render builtin:demo --orbit fast -o ${WORK}/good.png)
expect_failure(tile-kernels-word render builtin:demo --tile-kernels fast -o ${WORK}/good.png)
expect_failure(cells-composite-word render builtin:demo --cells-composite fast -o ${WORK}/good.png)
expect_failure(order-masks-word render builtin:demo --order-masks gpu -o ${WORK}/good.png)
expect_failure(tile-segments-word render builtin:demo --tile-segments yes -o ${WORK}/good.png)
expect_failure(bench-orbit-range bench --suite smoke --orbit -361 --out ${WORK}/bench)
execute_process(COMMAND mkfifo ${WORK}/image-fifo.png)
expect_failure(diff-fifo diff ${WORK}/good.png ${WORK}/image-fifo.png)
# Export of a scene as a mesh file.
expect_failure(export-bad-extension export builtin:soup:100 -o ${WORK}/soup.stl)
expect_failure(export-unwritable export builtin:soup:100 -o /nonexistent-folder/soup.ply)
expect_failure(export-bad-scene export builtin:hairball:0 -o ${WORK}/hair.ply)
# Textures and the atlas.
expect_failure(bad-atlas render builtin:textured:4 --atlas dense -o ${WORK}/good.png)
expect_failure(bad-textured-count render builtin:textured:0 -o ${WORK}/good.png)
file(WRITE ${WORK}/corrupt.png "\x89PNG this is not a png at all")
file(WRITE ${WORK}/uv.obj "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
expect_failure(texture-missing render ${WORK}/uv.obj --texture ${WORK}/nothing.png -o ${WORK}/good.png)
expect_failure(texture-corrupt render ${WORK}/uv.obj --texture ${WORK}/corrupt.png -o ${WORK}/good.png)
expect_failure(texture-without-uvs render builtin:demo --texture ${WORK}/good.png -o ${WORK}/good.png)
file(WRITE ${WORK}/tex.mtl "newmtl m\nKd 1 1 1\nmap_Kd corrupt.png\n")
file(WRITE ${WORK}/tex.obj "mtllib tex.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n")
expect_failure(mtl-corrupt-texture render ${WORK}/tex.obj -o ${WORK}/good.png)
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
string(JSON moving GET "${stats}" moving)
if(moving)
  message(SEND_ERROR "stats.json says a still view moved")
endif()

# A moving camera: with --order-reuse 0 every timed frame of cells orders a new view (none
# reuses the last order); by default the frames after one that ordered draw its order, checked.
execute_process(COMMAND ${STRATA} render builtin:demo --size 64x64 --method cells --frames 3
                        --orbit 5 --order-reuse 0 --cache ${WORK}/cells
                        --stats ${WORK}/moving.json -o ${WORK}/moving.png RESULT_VARIABLE rc)
file(READ ${WORK}/moving.json stats)
string(JSON moving GET "${stats}" moving)
string(JSON orbit GET "${stats}" orbit_deg)
string(JSON reused GET "${stats}" order_cached_frames)
if(NOT rc EQUAL 0 OR NOT moving OR NOT orbit EQUAL 5 OR NOT reused EQUAL 0)
  message(SEND_ERROR "--orbit 5: exit ${rc}, moving ${moving}, orbit_deg ${orbit}, "
                     "order_cached_frames ${reused} (expected 0)")
endif()
execute_process(COMMAND ${STRATA} render builtin:demo --size 64x64 --method cells --frames 3
                        --orbit 5 --cache ${WORK}/cells --stats ${WORK}/moving-reused.json
                        -o ${WORK}/moving-reused.png RESULT_VARIABLE rc)
file(READ ${WORK}/moving-reused.json stats)
string(JSON reused GET "${stats}" order_reused_frames)
string(JSON repaired GET "${stats}" order_repair_pixels)
if(NOT rc EQUAL 0 OR NOT reused EQUAL 3)
  message(SEND_ERROR "--orbit 5 (order reuse): exit ${rc}, order_reused_frames ${reused} "
                     "(expected 3), order_repair_pixels ${repaired}")
endif()
expect_failure(order-reuse-negative render builtin:demo --method cells --orbit 5 --order-reuse -1
               -o ${WORK}/good.png)
expect_failure(order-reuse-word render builtin:demo --method cells --orbit 5 --order-reuse many
               -o ${WORK}/good.png)

# Messages quoting input stay one printable line of bounded length: an escape sequence in a
# scene name is shown escaped, a 5000-character name is cut short.
string(ASCII 27 esc)
string(REPEAT "a" 5000 long_name)
foreach(name "builtin:${esc}[31mred${esc}]0;title" "builtin:${long_name}")
  execute_process(COMMAND ${STRATA} render "${name}" -o ${WORK}/good.png RESULT_VARIABLE rc
                  ERROR_VARIABLE err)
  string(LENGTH "${err}" err_length)
  string(FIND "${err}" "${esc}" has_escape)
  if(rc EQUAL 0 OR NOT has_escape EQUAL -1 OR err_length GREATER 600
     OR NOT err MATCHES "^strata: error: ")
    message(SEND_ERROR "message for a hostile scene name: exit ${rc}, ${err_length} bytes, "
                       "escape at ${has_escape}")
  endif()
endforeach()

# Mesa's rusticl (mesa-opencl-icd) shows no device unless RUSTICL_ENABLE names a driver: `info`
# lists it as a platform without devices, with that hint, and --device rusticl says so in one
# line instead of "no device matches".
if(EXISTS /etc/OpenCL/vendors/rusticl.icd)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=RUSTICL_ENABLE ${STRATA} info
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0 OR NOT out MATCHES "platform rusticl shows no device: set RUSTICL_ENABLE=llvmpipe")
    message(SEND_ERROR "info with rusticl installed: exit ${rc}, '${out}' '${err}'")
  endif()
  execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=RUSTICL_ENABLE ${STRATA} render
                          builtin:demo -s 16x16 --device rusticl -o ${WORK}/rusticl.png
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(rc EQUAL 0 OR NOT err MATCHES "^strata: error: OpenCL platform rusticl \\(matching 'rusticl'\\) has no device: set RUSTICL_ENABLE=llvmpipe[^\n]*\n$")
    message(SEND_ERROR "--device rusticl without RUSTICL_ENABLE: exit ${rc}, '${err}'")
  endif()
endif()

# A cache folder the OpenCL driver cannot use (XDG_CACHE_HOME is a file): the advice says so,
# not "install a driver".
file(WRITE ${WORK}/not-a-folder "")
execute_process(COMMAND ${CMAKE_COMMAND} -E env XDG_CACHE_HOME=${WORK}/not-a-folder ${STRATA} info
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "cache folder .*not-a-folder")
  message(SEND_ERROR "unusable XDG_CACHE_HOME: exit ${rc}, message '${err}'")
endif()

# An allocation failure (here under a 1 GB address-space limit) is a one-line error naming the
# scene, never an abort or an "internal error".
execute_process(COMMAND sh -c "ulimit -v 1000000; exec '${STRATA}' render builtin:crowd:100000 -m cells -s 64x64 --cache '${WORK}/cells-oom' -o '${WORK}/good.png'"
                RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
string(STRIP "${err}" err)
if(NOT rc EQUAL 1 OR NOT err MATCHES "^strata: error: builtin:crowd:100000: out of memory")
  message(SEND_ERROR "out of memory: exit ${rc}, message '${err}'")
endif()

# A NUL byte quoted from a file (a texture name in an MTL) is shown as \x00 and the message still
# states the problem after it.
execute_process(COMMAND sh -c "printf 'newmtl m\\nKd 1 1 1\\nmap_Kd abc\\000def.png\\n' > '${WORK}/nul.mtl'")
file(WRITE ${WORK}/nul.obj "mtllib nul.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n")
execute_process(COMMAND ${STRATA} render ${WORK}/nul.obj -s 32x32 -o ${WORK}/good.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "abc\\\\x00def\\.png: no such file")
  message(SEND_ERROR "NUL in a texture name: exit ${rc}, message '${err}'")
endif()

# A warning that quotes the file (a material library that is missing) shows a NUL byte as \x00.
execute_process(COMMAND sh -c "printf 'mtllib a\\000b.mtl\\nv 0 0 0\\nv 1 0 0\\nv 0 1 0\\nusemtl m\\nf 1 2 3\\n' > '${WORK}/nul-lib.obj'")
execute_process(COMMAND ${STRATA} render ${WORK}/nul-lib.obj -s 32x32 -o ${WORK}/nul-lib.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
string(FIND "${err}" "a\\x00b.mtl" escaped_at)
if(NOT rc EQUAL 0 OR escaped_at LESS 0)
  message(SEND_ERROR "NUL in a warning: exit ${rc}, message '${err}'")
endif()

# Outputs that are not plain files. Devices and FIFOs are written into, never replaced (a private
# null device stands in for /dev/null when running as root); a symbolic link stays a link; a
# read-only file is refused; a replaced file keeps its permissions; a file-size limit (a full
# disk) fails with one line and loses nothing.
function(expect_kind path kind name)
  execute_process(COMMAND stat -c %F ${path} OUTPUT_VARIABLE got OUTPUT_STRIP_TRAILING_WHITESPACE)
  if(NOT got STREQUAL "${kind}")
    message(SEND_ERROR "${name}: ${path} is a ${got}, expected a ${kind}")
  endif()
endfunction()
execute_process(COMMAND id -u OUTPUT_VARIABLE uid OUTPUT_STRIP_TRAILING_WHITESPACE)
if(uid STREQUAL "0")
  execute_process(COMMAND mknod ${WORK}/null-device.png c 1 3 RESULT_VARIABLE rc)
  if(rc EQUAL 0)
    execute_process(COMMAND ${STRATA} render builtin:demo -s 32x32 -o ${WORK}/null-device.png
                            --stats ${WORK}/null-device.png RESULT_VARIABLE rc)
    if(NOT rc EQUAL 0)
      message(SEND_ERROR "output to a device: exit ${rc}")
    endif()
    expect_kind(${WORK}/null-device.png "character special file" output-device)
  endif()
endif()
execute_process(COMMAND ${STRATA} render builtin:demo -s 32x32 --stats /dev/stdout
                OUTPUT_VARIABLE out RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR NOT out MATCHES "\"method\"")
  message(SEND_ERROR "--stats /dev/stdout: exit ${rc}, printed: ${out}")
endif()
execute_process(COMMAND mkfifo ${WORK}/out-fifo.png)
execute_process(COMMAND sh -c "cat '${WORK}/out-fifo.png' > '${WORK}/from-fifo.png' & '${STRATA}' render builtin:demo -s 32x32 -o '${WORK}/out-fifo.png'; s=$?; wait; exit $s"
                RESULT_VARIABLE rc TIMEOUT 120)
file(SIZE ${WORK}/from-fifo.png fifo_bytes)
if(NOT rc EQUAL 0 OR fifo_bytes LESS 100)
  message(SEND_ERROR "output to a FIFO: exit ${rc}, ${fifo_bytes} bytes came through")
endif()
expect_kind(${WORK}/out-fifo.png "fifo" output-fifo)
file(COPY_FILE ${WORK}/good.png ${WORK}/target.png)
file(CREATE_LINK target.png ${WORK}/link.png SYMBOLIC)
execute_process(COMMAND ${STRATA} render builtin:demo -s 48x48 -o ${WORK}/link.png RESULT_VARIABLE rc)
expect_kind(${WORK}/link.png "symbolic link" output-symlink)
file(SHA256 ${WORK}/target.png target_hash)
if(NOT rc EQUAL 0 OR target_hash STREQUAL good_hash)
  message(SEND_ERROR "output through a symbolic link: exit ${rc}, target rewritten: "
                     "${target_hash} vs ${good_hash}")
endif()
file(COPY_FILE ${WORK}/good.png ${WORK}/read-only.png)
file(CHMOD ${WORK}/read-only.png PERMISSIONS OWNER_READ GROUP_READ WORLD_READ)
expect_failure(output-read-only render builtin:demo -s 48x48 -o ${WORK}/read-only.png)
file(SHA256 ${WORK}/read-only.png ro_hash)
if(NOT ro_hash STREQUAL good_hash)
  message(SEND_ERROR "a read-only output was replaced")
endif()
file(COPY_FILE ${WORK}/good.png ${WORK}/private.png)
file(CHMOD ${WORK}/private.png PERMISSIONS OWNER_READ OWNER_WRITE)
execute_process(COMMAND ${STRATA} render builtin:demo -s 48x48 -o ${WORK}/private.png RESULT_VARIABLE rc)
execute_process(COMMAND stat -c %a ${WORK}/private.png OUTPUT_VARIABLE mode OUTPUT_STRIP_TRAILING_WHITESPACE)
if(NOT rc EQUAL 0 OR NOT mode STREQUAL "600")
  message(SEND_ERROR "a replaced output lost its permissions: exit ${rc}, mode ${mode}")
endif()
foreach(ext png jpg exr)
  execute_process(COMMAND ${STRATA} render builtin:demo -m embree -s 64x64 -o ${WORK}/limited.${ext})
  file(SHA256 ${WORK}/limited.${ext} before)
  execute_process(COMMAND sh -c "trap '' XFSZ; ulimit -f 2; exec '${STRATA}' render builtin:demo -m embree -s 256x256 --background 0.3,0.6,0.9 -o '${WORK}/limited.${ext}'"
                  RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
  string(STRIP "${err}" err)
  file(SHA256 ${WORK}/limited.${ext} after)
  if(rc EQUAL 0 OR NOT err MATCHES "^strata: error: [^\n]*limited" OR NOT before STREQUAL after)
    message(SEND_ERROR "full disk (${ext}): exit ${rc}, message '${err}', output kept: "
                       "${before} ${after}")
  endif()
endforeach()
# A signal during a write removes its temporary file: writing into a FIFO nobody reads blocks
# with the finished image in a temporary file, until SIGTERM.
set(tmp ${WORK}/tmp)
file(MAKE_DIRECTORY ${tmp})
execute_process(COMMAND mkfifo ${WORK}/unread-fifo.png)
execute_process(COMMAND sh -c "TMPDIR='${tmp}' '${STRATA}' render builtin:demo -s 32x32 -o '${WORK}/unread-fifo.png' & p=$!; for i in $(seq 100); do ls -A '${tmp}' | grep -q tmp && break; sleep 0.1; done; ls -A '${tmp}' > '${WORK}/tmp-during.txt'; kill -TERM $p; wait $p; exit 0"
                TIMEOUT 120)
file(READ ${WORK}/tmp-during.txt during)
execute_process(COMMAND ls -A ${tmp} OUTPUT_VARIABLE after_signal OUTPUT_STRIP_TRAILING_WHITESPACE)
if(NOT during MATCHES "tmp" OR after_signal)
  message(SEND_ERROR "SIGTERM during a write: temporary files before '${during}', after '${after_signal}'")
endif()

# Damaged program and cell caches are rebuilt, never trusted: a truncated program binary, a
# cache file that is a FIFO (reading it would block) and garbage in a cell cache file.
set(cache ${WORK}/xdg-cache)
function(render_with_cache name)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env XDG_CACHE_HOME=${cache}
                          ${STRATA} render builtin:demo --size 32x32 ${ARGN} -o ${WORK}/cache-${name}.png
                  RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
  if(NOT rc EQUAL 0 OR NOT EXISTS ${WORK}/cache-${name}.png)
    message(SEND_ERROR "cache ${name}: render failed (exit ${rc}): ${err}")
  endif()
endfunction()
render_with_cache(first --method cells)
# A run that compiles the kernels says so on a terminal (script(1) gives it one), with the
# seconds it took; redirected, it says nothing. PoCL's own cache is warm by now, so the compile
# strata asks for is quick.
find_program(SCRIPT script)
if(SCRIPT)
  file(REMOVE_RECURSE ${cache}/strata/programs)
  execute_process(COMMAND ${SCRIPT} -qec "env XDG_CACHE_HOME=${cache} ${STRATA} render builtin:demo --size 32x32 --method ppll -o ${WORK}/cache-tty.png" /dev/null
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 300)
  if(NOT rc EQUAL 0 OR NOT out MATCHES "strata: compiling the OpenCL kernels for [^\n]+ [0-9.]+ s")
    message(SEND_ERROR "compiling on a terminal: exit ${rc}, no notice in '${out}' '${err}'")
  endif()
  file(REMOVE_RECURSE ${cache}/strata/programs)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env XDG_CACHE_HOME=${cache}
                          ${STRATA} render builtin:demo --size 32x32 --method ppll -o ${WORK}/cache-quiet.png
                  RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
  if(NOT rc EQUAL 0 OR err MATCHES "compiling")
    message(SEND_ERROR "compiling, redirected: exit ${rc}, '${err}'")
  endif()
endif()
file(GLOB programs ${cache}/strata/programs/*.bin)
file(GLOB cell_files ${cache}/strata/cells/*.cells)
if(NOT programs OR NOT cell_files)
  message(SEND_ERROR "no program or cell cache file was written under ${cache}")
else()
  # Cut each binary after its header and a few bytes, as a full disk would.
  foreach(program ${programs})
    execute_process(COMMAND truncate -s 40 ${program} RESULT_VARIABLE trc)
    if(NOT trc EQUAL 0)
      message(SEND_ERROR "cannot truncate ${program}")
    endif()
  endforeach()
  foreach(cell_file ${cell_files})
    file(WRITE ${cell_file} "STRATACELLS and then nothing that makes sense")
  endforeach()
  render_with_cache(truncated --method cells)
  find_program(MKFIFO mkfifo)
  if(MKFIFO)
    foreach(program ${programs})
      file(REMOVE ${program})
      execute_process(COMMAND ${MKFIFO} ${program})
    endforeach()
    render_with_cache(fifo --method ppll)
  endif()
endif()

# The OpenCL driver's own kernel cache (PoCL's, under the same XDG_CACHE_HOME) with its kernel
# libraries cut short: PoCL would abort on loading one; strata removes them first, with a warning.
# A library PoCL is still linking (a "tempfile_XXXXXX.so" of another process, not whole yet)
# stays: removing it made that process abort.
file(GLOB_RECURSE pocl_kernels ${cache}/pocl/*.so)
if(pocl_kernels)
  foreach(kernel ${pocl_kernels})
    file(WRITE ${kernel} "\x7fELF cut short")
  endforeach()
  file(WRITE ${cache}/pocl/kcache/tempfile_Linkin.so "\x7fELF being linked")
  execute_process(COMMAND ${CMAKE_COMMAND} -E env XDG_CACHE_HOME=${cache}
                          ${STRATA} render builtin:demo --size 32x32 --method ppll
                          -o ${WORK}/cache-pocl-damaged.png
                  RESULT_VARIABLE rc ERROR_VARIABLE err TIMEOUT 300)
  if(NOT rc EQUAL 0 OR NOT EXISTS ${WORK}/cache-pocl-damaged.png OR
     NOT err MATCHES "removed [0-9]+ damaged kernel libraries")
    message(SEND_ERROR "a damaged PoCL kernel cache: exit ${rc}: ${err}")
  endif()
  if(NOT EXISTS ${cache}/pocl/kcache/tempfile_Linkin.so)
    message(SEND_ERROR "a kernel library PoCL was still linking was removed")
  endif()
endif()
