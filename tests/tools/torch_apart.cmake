# cmake -DLIGHT=... -DNETWORK=... -P torch_apart.cmake: fails unless LIGHT (patchgraph) has no
# LibTorch library among the libraries it loads and NETWORK (patchgraph-torch) has: loading
# LibTorch costs every start of patchgraph about 0.6 s (tools/CMakeLists.txt).
cmake_minimum_required(VERSION 3.20)

# Sets `found` to whether `binary` loads libtorch_cpu: the dynamic loader lists every library it
# would load, with those that libraries bring in.
function(loads_torch binary)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env LD_TRACE_LOADED_OBJECTS=1 "${binary}"
                  OUTPUT_VARIABLE loaded RESULT_VARIABLE status)
  string(FIND "${loaded}" "libc.so" libc)
  if(NOT status EQUAL 0 OR libc EQUAL -1)
    message(FATAL_ERROR "no library list from ${binary} (${status}):\n${loaded}")
  endif()
  string(FIND "${loaded}" "libtorch_cpu.so" torch)
  if(torch EQUAL -1)
    set(found FALSE PARENT_SCOPE)
  else()
    set(found TRUE PARENT_SCOPE)
  endif()
endfunction()

loads_torch("${LIGHT}")
if(found)
  message(FATAL_ERROR "${LIGHT} loads LibTorch")
endif()
loads_torch("${NETWORK}")
if(NOT found)
  message(FATAL_ERROR "${NETWORK} does not load LibTorch")
endif()
message(STATUS "${LIGHT}: no LibTorch; ${NETWORK}: LibTorch")
