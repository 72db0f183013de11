# The ROS ring: messages, services and catkin_package(). Included before any target is defined,
# because catkin_package() sets the output folders that every later target uses.
#
# Components the messages need are required for the ring; if one is missing the ring is switched off
# with a message (the core still builds), never a failed configure.
set(DQO_ROS_MSG_COMPONENTS message_generation std_msgs geometry_msgs sensor_msgs)
set(DQO_ROS_NODE_COMPONENTS roscpp rosbag tf2_msgs tf2_ros message_filters nav_msgs visualization_msgs rostest
                             nodelet diagnostic_msgs roslib)

set(_dqo_missing "")
foreach(_c ${DQO_ROS_MSG_COMPONENTS} ${DQO_ROS_NODE_COMPONENTS})
  find_package(${_c} QUIET NO_MODULE)
  if(NOT ${_c}_FOUND)
    list(APPEND _dqo_missing ${_c})
  endif()
endforeach()
if(_dqo_missing)
  message(STATUS "dqo_map: ROS packages missing (${_dqo_missing}): the ROS ring is left out")
  set(DQO_WITH_ROS OFF)
  set(DQO_WITH_ROS OFF CACHE BOOL "" FORCE)
  return()
endif()

find_package(catkin REQUIRED COMPONENTS ${DQO_ROS_MSG_COMPONENTS} ${DQO_ROS_NODE_COMPONENTS})

add_message_files(DIRECTORY msg FILES
  Detection.msg
  DetectionArray.msg
  KeyFrame.msg
  KeyFramePoses.msg
  Object.msg
  ObjectArray.msg
  ObjectEvent.msg
  KeyFrameObjects.msg
)
add_service_files(DIRECTORY srv FILES
  ListObjects.srv
  GetObject.srv
  ExtractObject.srv
  SaveMap.srv
  LoadMap.srv
)
generate_messages(DEPENDENCIES std_msgs geometry_msgs sensor_msgs)

# Libraries of the core that downstream catkin packages may link (those whose dependencies exist).
set(DQO_EXPORTED_LIBRARIES dqo_geometry dqo_common)
if(DQO_HAVE_YAML)
  list(APPEND DQO_EXPORTED_LIBRARIES dqo_config dqo_sim)
endif()
if(DQO_HAVE_OPENCV AND DQO_HAVE_OPEN3D AND DQO_HAVE_YAML)
  list(APPEND DQO_EXPORTED_LIBRARIES dqo_io)
endif()
if(DQO_HAVE_OPENCV AND DQO_HAVE_CERES)
  list(APPEND DQO_EXPORTED_LIBRARIES dqo_tracking)
endif()
if(DQO_HAVE_CERES AND DQO_HAVE_YAML)
  list(APPEND DQO_EXPORTED_LIBRARIES dqo_objects)
endif()
list(APPEND DQO_EXPORTED_LIBRARIES dqo_eval dqo_gaussians)
# Static libraries: dependents must come before their dependencies on the link line.
list(REVERSE DQO_EXPORTED_LIBRARIES)
catkin_package(
  INCLUDE_DIRS include
  LIBRARIES ${DQO_EXPORTED_LIBRARIES}
  CATKIN_DEPENDS message_runtime std_msgs geometry_msgs sensor_msgs roscpp
  DEPENDS EIGEN3
)

set(DQO_INCLUDE_DESTINATION ${CATKIN_GLOBAL_INCLUDE_DESTINATION})
set(DQO_LIB_DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})
set(DQO_BIN_DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
