# Robot kinematics for robot mode (server/robot): the URDF parsed by urdfdom (Debian:
# liburdfdom-dev), turned into a KDL tree by kdl_parser (libkdl-parser-dev), forward and inverse
# kinematics by Orocos KDL (liborocos-kdl-dev). kdl_parser's CMake config is catkin-generated and
# drags in ROS packages, so the three libraries are found directly: gd::kdl.
find_path(GD_KDL_INCLUDE kdl/chain.hpp PATHS /usr/include)
find_path(GD_KDL_PARSER_INCLUDE kdl_parser/kdl_parser.hpp PATHS /usr/include)
find_path(GD_URDFDOM_INCLUDE urdf_parser/urdf_parser.h PATHS /usr/include)
find_library(GD_KDL_LIB orocos-kdl)
find_library(GD_KDL_PARSER_LIB kdl_parser)
find_library(GD_URDFDOM_MODEL_LIB urdfdom_model)
foreach(v GD_KDL_INCLUDE GD_KDL_PARSER_INCLUDE GD_URDFDOM_INCLUDE GD_KDL_LIB GD_KDL_PARSER_LIB GD_URDFDOM_MODEL_LIB)
  if(NOT ${v})
    message(FATAL_ERROR "${v} not found: install liborocos-kdl-dev libkdl-parser-dev liburdfdom-dev (scripts/build does)")
  endif()
endforeach()
add_library(gd_kdl INTERFACE)
target_include_directories(gd_kdl SYSTEM INTERFACE ${GD_KDL_INCLUDE} ${GD_KDL_PARSER_INCLUDE} ${GD_URDFDOM_INCLUDE})
target_link_libraries(gd_kdl INTERFACE ${GD_KDL_PARSER_LIB} ${GD_KDL_LIB} ${GD_URDFDOM_MODEL_LIB})
add_library(gd::kdl ALIAS gd_kdl)
