# Shared by the interface packages under interfaces/: build them with the rosidl tool chain that
# the pip-installed ROS 2 Jazzy wheels carry (tools/build_interfaces.py runs cmake).
#
# The wheels' exported targets <pkg>::<pkg>__rosidl_generator_py name the include directories of
# the Python and numpy that built the wheels (/opt/python/cp311-cp311/...), which do not exist
# here. cosim_fix_wheel_python_includes() points every such directory of every imported target at
# this interpreter's Python and numpy headers. Call it after the last find_package() of a package
# whose Python bindings the generated code links (for actions: action_msgs, service_msgs too).
macro(cosim_fix_wheel_python_includes)
  find_package(Python3 REQUIRED COMPONENTS Interpreter Development.Module NumPy)
  get_property(_cosim_targets DIRECTORY PROPERTY IMPORTED_TARGETS)
  foreach(_cosim_target IN LISTS _cosim_targets)
    get_target_property(_cosim_dirs ${_cosim_target} INTERFACE_INCLUDE_DIRECTORIES)
    if(NOT _cosim_dirs)
      continue()
    endif()
    set(_cosim_fixed "")
    foreach(_cosim_dir IN LISTS _cosim_dirs)
      if(EXISTS "${_cosim_dir}" OR _cosim_dir MATCHES "^\\$<")
        list(APPEND _cosim_fixed "${_cosim_dir}")
      elseif(_cosim_dir MATCHES "numpy")
        list(APPEND _cosim_fixed ${Python3_NumPy_INCLUDE_DIRS})
      elseif(_cosim_dir MATCHES "include/python3")
        list(APPEND _cosim_fixed ${Python3_INCLUDE_DIRS})
      else()
        list(APPEND _cosim_fixed "${_cosim_dir}")
      endif()
    endforeach()
    if(NOT "${_cosim_fixed}" STREQUAL "${_cosim_dirs}")
      set_target_properties(${_cosim_target} PROPERTIES
        INTERFACE_INCLUDE_DIRECTORIES "${_cosim_fixed}")
    endif()
  endforeach()
endmacro()
