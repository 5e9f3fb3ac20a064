# The PyPI wheels of ROS 2's message packages export the Python include path of the machine that built them
# (/opt/python/...): point their imported Python targets at this interpreter's headers instead.
# Installed libraries find each other and the wheels' libraries in <prefix>/lib (the venv's), where the wheels'
# bootstrapper puts LD_LIBRARY_PATH; the RPATH makes them load without it too.
find_package(Python3 REQUIRED COMPONENTS Interpreter Development)
set(CMAKE_INSTALL_RPATH "$ORIGIN;$ORIGIN/../../..;${CMAKE_INSTALL_PREFIX}/lib")
macro(fix_python_includes)
  foreach(pkg ${ARGN})
    set(tgt ${pkg}::${pkg}__rosidl_generator_py)
    if(TARGET ${tgt})
      get_target_property(dirs ${tgt} INTERFACE_INCLUDE_DIRECTORIES)
      list(FILTER dirs EXCLUDE REGEX "^/opt/python/")
      list(APPEND dirs ${Python3_INCLUDE_DIRS})
      set_target_properties(${tgt} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${dirs}")
    endif()
  endforeach()
endmacro()

# rclpy loads a message package's C typesupports only (through its Python extension). With
# -DZEBRA_SIM_PYTHON_ONLY=ON (as scripts/build_interfaces.sh builds into the venv) the C++ generators are dropped
# from the extensions rosidl_generate_interfaces runs: rosidl_generator_cpp and the cpp, fastrtps_cpp and
# introspection_cpp typesupports, a third of the build's time. Off by default, so a ROS 2 workspace (colcon) builds the
# whole package, C++ headers included.
option(ZEBRA_SIM_PYTHON_ONLY "generate the C and Python code only" OFF)
macro(python_only_generators)
  if(ZEBRA_SIM_PYTHON_ONLY)
    list(FILTER AMENT_EXTENSIONS_rosidl_generate_idl_interfaces EXCLUDE REGEX "_cpp:")
  endif()
endmacro()
