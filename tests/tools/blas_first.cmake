# cmake -DBINARY=... -P blas_first.cmake: fails unless OpenBLAS comes before ATLAS's libf77blas
# among the binary's libraries. The first library that defines sgemm_ answers LibTorch's matrix
# products for the whole program; Ceres brings in ATLAS's, which made the learned normals' inference
# in patchgraph 1.4-2.7x slower (tools/CMakeLists.txt).
execute_process(COMMAND readelf -d "${BINARY}" OUTPUT_VARIABLE dynamic RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "readelf -d ${BINARY} failed (${status})")
endif()
string(FIND "${dynamic}" "[libopenblas.so.0]" openblas)
string(FIND "${dynamic}" "[libf77blas.so" atlas)
if(openblas EQUAL -1)
  message(FATAL_ERROR "${BINARY} does not load OpenBLAS (libopenblas.so.0):\n${dynamic}")
endif()
if(NOT atlas EQUAL -1 AND atlas LESS openblas)
  message(FATAL_ERROR "${BINARY} loads ATLAS's libf77blas before OpenBLAS:\n${dynamic}")
endif()
message(STATUS "${BINARY}: OpenBLAS first")
