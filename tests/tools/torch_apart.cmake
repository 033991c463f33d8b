# cmake -DLAUNCHER=... -DLIGHT=... -DNETWORK=... -P torch_apart.cmake: fails unless LIGHT
# (patchgraph-core) loads neither LibTorch nor OpenImageIO at its start, NETWORK
# (patchgraph-torch) loads LibTorch and not OpenImageIO, and LAUNCHER (patchgraph) loads neither:
# LibTorch costs every start about 0.6 s (tools/CMakeLists.txt), OpenImageIO's libraries about
# 0.5 s; those come with the image codec module when a program first reads or writes an image
# that is neither PNG nor EXR (core/src/image_formats.h).
cmake_minimum_required(VERSION 3.20)

# Sets `torch_cpu` and `OpenImageIO` to whether `binary` loads those libraries: the dynamic
# loader lists every library it would load, with those that libraries bring in.
function(loaded_by binary)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env LD_TRACE_LOADED_OBJECTS=1 "${binary}"
                  OUTPUT_VARIABLE loaded RESULT_VARIABLE status)
  string(FIND "${loaded}" "libc.so" libc)
  if(NOT status EQUAL 0 OR libc EQUAL -1)
    message(FATAL_ERROR "no library list from ${binary} (${status}):\n${loaded}")
  endif()
  foreach(library torch_cpu OpenImageIO)
    string(FIND "${loaded}" "lib${library}.so" at)
    if(at EQUAL -1)
      set(${library} FALSE PARENT_SCOPE)
    else()
      set(${library} TRUE PARENT_SCOPE)
    endif()
  endforeach()
endfunction()

loaded_by("${LAUNCHER}")
if(torch_cpu OR OpenImageIO)
  message(FATAL_ERROR "${LAUNCHER} loads LibTorch or OpenImageIO")
endif()
loaded_by("${LIGHT}")
if(torch_cpu OR OpenImageIO)
  message(FATAL_ERROR "${LIGHT} loads LibTorch or OpenImageIO")
endif()
loaded_by("${NETWORK}")
if(NOT torch_cpu)
  message(FATAL_ERROR "${NETWORK} does not load LibTorch")
endif()
if(OpenImageIO)
  message(FATAL_ERROR "${NETWORK} loads OpenImageIO at its start")
endif()
message(STATUS "${LAUNCHER}: neither LibTorch nor OpenImageIO; ${LIGHT}: neither; "
               "${NETWORK}: LibTorch alone")
