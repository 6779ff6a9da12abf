# Code that is not on a hot path compiled with -O1 instead of the build type's -O3 (issue 31,
# docs/architecture.md "Build time"): the GoogleTest binaries, the test helper programs, the mains
# that parse command lines and the benchmarks that only time library calls. Why: CLI11 is
# header-only in Debian 12 and its inline code costs ~6 s of -O3 code generation in every main (~3
# s at -O1), and a test file's -O3 pass costs about a third of its compile time. What these files
# run that is hot (VO, BA, place recognition, the renderer, DDS) lives in libraries that keep full
# optimization, and so do the benchmarks that time code of their own files (bench_feature,
# bench_solvers, bench_optimization). Floating-point results do not change with the level (no
# -ffast-math, no FMA contraction without -mfma), so tests see the same numbers.
# CCM_LIGHT_OPTIMIZATION=OFF compiles everything at the build type's level.
option(CCM_LIGHT_OPTIMIZATION "Compile tests and command-line mains with -O1 in optimized builds" ON)
set(_ccm_light_flag
    "$<$<AND:$<BOOL:${CCM_LIGHT_OPTIMIZATION}>,$<OR:$<CONFIG:Release>,$<CONFIG:RelWithDebInfo>>>:-O1>")

# ccm_optimize_lightly(TARGETS t...): every source of these targets.
function(ccm_optimize_lightly)
  cmake_parse_arguments(ARG "" "" "TARGETS" ${ARGN})
  foreach(target IN LISTS ARG_TARGETS)
    if(NOT TARGET ${target})
      message(FATAL_ERROR "ccm_optimize_lightly: no target ${target}")
    endif()
    # After the build type's flags on the command line, so it wins.
    target_compile_options(${target} PRIVATE ${_ccm_light_flag})
  endforeach()
endfunction()
