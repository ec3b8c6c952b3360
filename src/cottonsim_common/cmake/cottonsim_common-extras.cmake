# The build of a CottonSim Python package, exported to the packages that
# find_package(catkin REQUIRED COMPONENTS cottonsim_common) (catkin CFG_EXTRAS).
#
# cottonsim_python_package([SHARE_DIRS dir ...])
#   catkin_python_setup() and catkin_package() of the calling package, every
#   executable in its nodes/ and scripts/ installed as a ROS executable (the
#   glob runs at configure time: a new executable needs a re-configure), and
#   SHARE_DIRS (config, launch, ...) installed to the package's share folder.
#   A macro, not a function: catkin_package() must run in the package's scope.
macro(cottonsim_python_package)
  cmake_parse_arguments(_cottonsim "" "" "SHARE_DIRS" ${ARGN})
  catkin_python_setup()
  catkin_package()
  file(GLOB _cottonsim_executables RELATIVE ${CMAKE_CURRENT_SOURCE_DIR} nodes/* scripts/*)
  if(_cottonsim_executables)
    catkin_install_python(PROGRAMS ${_cottonsim_executables}
      DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
  endif()
  if(_cottonsim_SHARE_DIRS)
    install(DIRECTORY ${_cottonsim_SHARE_DIRS} DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})
  endif()
endmacro()
