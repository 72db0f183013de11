# Helpers that hide the difference between the catkin build and the plain CMake build.
if(NOT DEFINED DQO_INCLUDE_DESTINATION)
  include(GNUInstallDirs)
  set(DQO_INCLUDE_DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  set(DQO_LIB_DESTINATION ${CMAKE_INSTALL_LIBDIR})
  set(DQO_BIN_DESTINATION ${CMAKE_INSTALL_LIBDIR}/dqo_map)
  set(CMAKE_RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/bin)
endif()

# dqo_add_library(NAME SOURCES ... [PUBLIC_LIBS ...] [PRIVATE_LIBS ...])
# A static library of the core with the package's include folder.
function(dqo_add_library name)
  cmake_parse_arguments(A "" "" "SOURCES;PUBLIC_LIBS;PRIVATE_LIBS" ${ARGN})
  add_library(${name} STATIC ${A_SOURCES})
  target_include_directories(${name} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:${DQO_INCLUDE_DESTINATION}>)
  target_link_libraries(${name} PUBLIC ${A_PUBLIC_LIBS} PRIVATE ${A_PRIVATE_LIBS})
  install(TARGETS ${name}
    ARCHIVE DESTINATION ${DQO_LIB_DESTINATION}
    LIBRARY DESTINATION ${DQO_LIB_DESTINATION})
endfunction()

# dqo_add_gtest(NAME SOURCES ... [LIBS ...])
# A GoogleTest executable registered with catkin (run_tests) or with CTest.
# Tests find their data through DQO_SOURCE_DIR.
function(dqo_add_gtest name)
  cmake_parse_arguments(A "" "" "SOURCES;LIBS" ${ARGN})
  if(DQO_WITH_ROS)
    catkin_add_gtest(${name} ${A_SOURCES})
    if(NOT TARGET ${name})
      return()
    endif()
    target_link_libraries(${name} GTest::gtest_main ${A_LIBS})
  else()
    add_executable(${name} ${A_SOURCES})
    target_link_libraries(${name} GTest::gtest_main ${A_LIBS})
    add_test(NAME ${name} COMMAND ${name})
  endif()
  target_compile_definitions(${name} PRIVATE DQO_SOURCE_DIR="${DQO_SOURCE_DIR}")
endfunction()

# dqo_add_tool(NAME SOURCES ... [LIBS ...])
# A command-line tool or benchmark: `rosrun dqo_map NAME` or `scripts/dqo NAME`.
function(dqo_add_tool name)
  cmake_parse_arguments(A "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${A_SOURCES})
  target_link_libraries(${name} ${A_LIBS})
  target_compile_definitions(${name} PRIVATE DQO_SOURCE_DIR="${DQO_SOURCE_DIR}")
  install(TARGETS ${name} RUNTIME DESTINATION ${DQO_BIN_DESTINATION})
endfunction()
