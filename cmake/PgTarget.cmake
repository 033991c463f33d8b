# One place that sets the language standard and warnings on every target of the project.
function(pg_target_defaults target)
  target_compile_features(${target} PUBLIC cxx_std_17)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  target_compile_options(${target} PRIVATE -Wall -Wextra)
  # Eigen objects cross into Debian's prebuilt libraries (Ceres was built for baseline x86-64,
  # where Eigen aligns to 16 bytes). Keep that alignment whatever -march says, or memory that
  # one side allocates the other frees with the wrong allocator.
  target_compile_definitions(${target} PUBLIC EIGEN_MAX_ALIGN_BYTES=16)
  if(PG_NATIVE)
    # Built and run on the same machine (as the README commands do): use its vector units.
    target_compile_options(${target} PRIVATE -march=native)
    # GCC 12 reports false -Wmaybe-uninitialized inside its own AVX-512 intrinsics when it
    # inlines Eigen's vectorised kernels, and on AVX2 machines (no AVX-512) a false
    # -Warray-bounds for a 4-double load (_mm256_loadu_pd) from a 3-vector in Eigen's fixed-size
    # assignment loops (21 of them in a build on an EPYC; the tests of the functions they name,
    # SE3 log and the point-to-plane residuals, run clean under AddressSanitizer there). Neither
    # says anything about this project's code.
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
      target_compile_options(${target} PRIVATE -Wno-maybe-uninitialized -Wno-array-bounds)
    endif()
  endif()
endfunction()
