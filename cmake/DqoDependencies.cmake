# Finds the core's dependencies. Eigen is required; everything else is optional and only drops the
# libraries that need it, with a STATUS message saying so.
find_package(Eigen3 3.3 REQUIRED NO_MODULE)

find_package(yaml-cpp QUIET)
if(yaml-cpp_FOUND)
  set(DQO_HAVE_YAML ON)
  # Debian 12's yaml-cpp 0.7 exports the plain name `yaml-cpp`; newer releases also yaml-cpp::yaml-cpp.
  if(TARGET yaml-cpp::yaml-cpp)
    set(DQO_YAML_TARGET yaml-cpp::yaml-cpp)
  else()
    set(DQO_YAML_TARGET yaml-cpp)
  endif()
else()
  set(DQO_HAVE_YAML OFF)
  message(STATUS "dqo_map: yaml-cpp not found: sim/ and YAML configuration are left out")
endif()

find_package(OpenCV QUIET COMPONENTS core imgproc imgcodecs features2d calib3d)
set(DQO_HAVE_OPENCV ${OpenCV_FOUND})
if(NOT OpenCV_FOUND)
  message(STATUS "dqo_map: OpenCV not found: io/ and tracking/ are left out")
endif()
# The YOLO detector needs OpenCV's DNN module (Debian: libopencv-dnn-dev, part of libopencv-dev).
set(DQO_HAVE_OPENCV_DNN OFF)
if(OpenCV_FOUND AND TARGET opencv_dnn)
  set(DQO_HAVE_OPENCV_DNN ON)
elseif(OpenCV_FOUND)
  message(STATUS "dqo_map: OpenCV has no dnn module: detector/ is left out")
endif()

find_package(Ceres QUIET)
set(DQO_HAVE_CERES ${Ceres_FOUND})
if(NOT Ceres_FOUND)
  message(STATUS "dqo_map: Ceres not found: tracking/ and objects/ are left out")
endif()

find_package(Open3D QUIET)
set(DQO_HAVE_OPEN3D ${Open3D_FOUND})
if(NOT Open3D_FOUND)
  message(STATUS "dqo_map: Open3D not found: mesh/ and mesh I/O are left out")
endif()

find_package(Threads REQUIRED)

# GoogleTest: catkin brings its own (catkin_add_gtest); the plain build needs an installed GTest.
if(DQO_BUILD_TESTS AND NOT DQO_WITH_ROS)
  find_package(GTest QUIET)
  if(NOT GTest_FOUND)
    message(STATUS "dqo_map: GoogleTest not found: unit tests are left out")
    set(DQO_BUILD_TESTS OFF)
  endif()
endif()
