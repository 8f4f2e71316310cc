# Injected with -DCMAKE_PROJECT_INCLUDE=... when msg_defs/ is built against the ROS 2 wheels in .venv/.
# The wheels' exported CMake targets carry include directories of the machine that built them
# (/opt/python/cp311-cp311/include/python3.11). They do not exist here and make configure fail.
# At the end of configure, drop every non-existent /opt/python entry from the imported targets.
# Not used (and not needed) on a regular ROS 2 install with colcon.
cmake_minimum_required(VERSION 3.21)

function(_air_hockey_drop_missing_includes)
  get_property(_targets DIRECTORY "${CMAKE_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    get_target_property(_dirs ${_target} INTERFACE_INCLUDE_DIRECTORIES)
    if(NOT _dirs)
      continue()
    endif()
    set(_kept "")
    foreach(_dir IN LISTS _dirs)
      if(_dir MATCHES "^/opt/python/" AND NOT EXISTS "${_dir}")
        continue()
      endif()
      list(APPEND _kept "${_dir}")
    endforeach()
    set_target_properties(${_target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_kept}")
  endforeach()
endfunction()

cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL _air_hockey_drop_missing_includes)
