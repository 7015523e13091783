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

# cosim_generate_interfaces(<rosidl_generate_interfaces arguments>): rosidl_generate_interfaces
# for rclpy only, compiled in fewer translation units. Call after the last find_package().
#
# rclpy needs of an interface package only its C type supports (the dispatcher
# <pkg>__rosidl_typesupport_c, Fast DDS's <pkg>__rosidl_typesupport_fastrtps_c, which rmw_zenoh
# uses too, and the introspection C library) and its Python bindings; the C++ generators and type
# supports are nearly half of the compile and nothing in a pip-only install loads them. rosidl_generate_interfaces runs every
# extension registered, and the wheels' exported dependencies register the C++ ones whatever the
# package asks for, so they are filtered out of that list (as rosidlcpp does). The introspection C
# type support stays: rmw_fastrtps_cpp builds each type's DDS TypeObject from it when a publisher
# or subscription registers the type (without it the second registration of a type fails as
# "incompatible").
#
# A generated file's compile is mostly the parsing of headers, so the targets whose generated
# files can share one translation unit are unity builds (each file still compiled once, with the
# same flags). rosidl_generator_c's files cannot: each defines the same static names.
macro(cosim_generate_interfaces)
  list(FILTER AMENT_EXTENSIONS_rosidl_generate_idl_interfaces EXCLUDE REGEX
    "^rosidl_(generator_cpp|typesupport_cpp|typesupport_fastrtps_cpp|typesupport_introspection_cpp):")
  rosidl_generate_interfaces(${ARGN})
  foreach(_cosim_generator rosidl_typesupport_fastrtps_c rosidl_typesupport_introspection_c
      rosidl_typesupport_c rosidl_generator_py)
    set_target_properties(${PROJECT_NAME}__${_cosim_generator} PROPERTIES UNITY_BUILD ON)
  endforeach()
endmacro()
