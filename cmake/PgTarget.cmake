# One place that sets the language standard and warnings on every target of the project.
function(pg_target_defaults target)
  target_compile_features(${target} PUBLIC cxx_std_17)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  target_compile_options(${target} PRIVATE -Wall -Wextra)
  if(PG_NATIVE)
    # Built and run on the same machine (as the README commands do): use its vector units.
    target_compile_options(${target} PRIVATE -march=native)
  endif()
endfunction()
