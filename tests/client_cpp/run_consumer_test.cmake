# ctest gd_client_find_package: installs the `client` component of the build into a fresh prefix,
# configures and builds find_package_consumer/ against it and runs the consumer.
#   cmake -DBUILD_DIR=<gd build> -DSOURCE_DIR=<this dir> -DWORK_DIR=<scratch> -P run_consumer_test.cmake
foreach(v BUILD_DIR SOURCE_DIR WORK_DIR)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "run_consumer_test.cmake needs -D${v}=...")
  endif()
endforeach()
file(REMOVE_RECURSE ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  message(STATUS "${out}")
endfunction()

run(${CMAKE_COMMAND} --install ${BUILD_DIR} --component client --prefix ${prefix})
foreach(pattern include/gd/client.h lib*/libgd_client.a lib*/cmake/GarmentDynamicsClient/GarmentDynamicsClientConfig.cmake)
  file(GLOB_RECURSE found ${prefix}/${pattern})
  if(NOT found)
    file(GLOB found ${prefix}/${pattern})
  endif()
  if(NOT found)
    message(FATAL_ERROR "the install lacks ${pattern}")
  endif()
endforeach()
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/find_package_consumer -B ${WORK_DIR}/build -G Ninja
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${prefix})
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build)
run(${WORK_DIR}/build/consumer 127.0.0.1:1)
