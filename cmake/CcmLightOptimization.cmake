# Code that is not on a hot path compiled with -O1 instead of the build type's -O3 (issue 31,
# docs/architecture.md "Build time"): the GoogleTest binaries, the test helper programs and the
# mains that parse command lines. Why: CLI11 is header-only in Debian 12 and its inline code
# costs ~6 s of -O3 code generation in every main (~3 s at -O1), and a test file's -O3 pass
# costs about a third of its compile time. What these files run that is hot (VO, BA, place
# recognition, the renderer, DDS) lives in libraries that keep full optimization, and so do the
# benchmarks, whose own files build problems and time them. Floating-point results do not
# change with the level (no -ffast-math, no FMA contraction without -mfma), so tests see the
# same numbers. CCM_LIGHT_OPTIMIZATION=OFF compiles everything at the build type's level.
option(CCM_LIGHT_OPTIMIZATION "Compile tests and command-line mains with -O1 in optimized builds" ON)
set(_ccm_light_flag
    "$<$<AND:$<BOOL:${CCM_LIGHT_OPTIMIZATION}>,$<OR:$<CONFIG:Release>,$<CONFIG:RelWithDebInfo>>>:-O1>")

# ccm_optimize_lightly(TARGETS t... ) : every source of these targets.
# ccm_optimize_lightly(SOURCES f...) : these files of the calling directory only (a main beside
#   hot sources of the same target); the files then leave the target's unity batches.
function(ccm_optimize_lightly)
  cmake_parse_arguments(ARG "" "" "TARGETS;SOURCES" ${ARGN})
  foreach(target IN LISTS ARG_TARGETS)
    if(NOT TARGET ${target})
      message(FATAL_ERROR "ccm_optimize_lightly: no target ${target}")
    endif()
    # After the build type's flags on the command line, so it wins.
    target_compile_options(${target} PRIVATE ${_ccm_light_flag})
  endforeach()
  if(ARG_SOURCES)
    set_source_files_properties(${ARG_SOURCES} PROPERTIES COMPILE_OPTIONS ${_ccm_light_flag})
  endif()
endfunction()
