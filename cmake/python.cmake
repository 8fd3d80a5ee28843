# The Python module (python/, docs/python.md): built when pybind11 and the Python headers are found.
# Sets FLUORO_WITH_PYTHON (python/CMakeLists.txt compiles the libraries it links as
# position-independent code).
set(FLUORO_WITH_PYTHON OFF)
if(FLUORO_PYTHON)
  # Debian's python3, whose dist-packages hold the numpy and pytest scripts/setup.sh installs
  # (ahead of another python3 on the PATH), unless Python3_EXECUTABLE is given.
  if(NOT DEFINED Python3_EXECUTABLE AND EXISTS /usr/bin/python3)
    set(Python3_EXECUTABLE /usr/bin/python3)
  endif()
  find_package(Python3 COMPONENTS Interpreter Development.Module)
  if(Python3_FOUND)
    set(PYBIND11_FINDPYTHON ON)
    find_package(pybind11 2.10 CONFIG QUIET)
  endif()
  if(Python3_FOUND AND pybind11_FOUND)
    set(FLUORO_WITH_PYTHON ON)
  else()
    message(STATUS "fluoro: building without the Python module (Python headers: ${Python3_FOUND}, pybind11: ${pybind11_FOUND})")
  endif()
endif()
