# Compiles SRC (syntax only) and passes when compilation FAILS with a message containing EXPECT.
execute_process(COMMAND ${CXX} -std=c++20 -fsyntax-only -fopenmp -I${INCLUDES} -I/usr/include/eigen3 ${SRC}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0)
  message(FATAL_ERROR "${SRC} compiled, but it must not")
endif()
string(FIND "${err}" "${EXPECT}" pos)
if(pos EQUAL -1)
  message(FATAL_ERROR "${SRC} failed to compile, but without the expected message '${EXPECT}':\n${err}")
endif()
message(STATUS "failed to compile as intended: ${EXPECT}")
