# Decides whether the Python module is built (STREAMCVD_PYTHON) and finds the interpreter it is
# built for. The interpreter: Python_EXECUTABLE when given, else Debian's /usr/bin/python3 when it
# exists (the one python3-numpy, pybind11-dev and python3-pytest serve; a pyenv or venv python
# earlier on PATH has neither), else the first python3 FindPython sees.
set(STREAMCVD_PYTHON "AUTO" CACHE STRING "Build the Python module: ON, OFF or AUTO (when pybind11 and numpy are found)")
set_property(CACHE STREAMCVD_PYTHON PROPERTY STRINGS AUTO ON OFF)

if(STREAMCVD_SANITIZE AND NOT STREAMCVD_PYTHON STREQUAL "OFF")
  message(STATUS "streamcvd: Python module skipped (STREAMCVD_SANITIZE=${STREAMCVD_SANITIZE}: an instrumented extension "
                 "cannot be loaded into an uninstrumented python)")
  return()
endif()
if(STREAMCVD_PYTHON STREQUAL "OFF")
  return()
endif()

if(NOT Python_EXECUTABLE AND EXISTS /usr/bin/python3)
  set(Python_EXECUTABLE /usr/bin/python3 CACHE FILEPATH "Python interpreter of the streamcvd module")
endif()
find_package(Python 3.8 COMPONENTS Interpreter Development.Module)
set(_streamcvd_python_ok FALSE)
if(Python_FOUND)
  find_package(pybind11 2.6 CONFIG QUIET)
  execute_process(COMMAND ${Python_EXECUTABLE} -c "import numpy" RESULT_VARIABLE _numpy_rc OUTPUT_QUIET ERROR_QUIET)
  if(pybind11_FOUND AND _numpy_rc EQUAL 0)
    set(_streamcvd_python_ok TRUE)
  endif()
endif()

if(NOT _streamcvd_python_ok)
  if(STREAMCVD_PYTHON STREQUAL "ON")
    message(FATAL_ERROR "STREAMCVD_PYTHON=ON needs pybind11 (pybind11-dev), Python headers (python3-dev) and numpy "
                        "(python3-numpy) for ${Python_EXECUTABLE}; tools/install_deps.sh installs them")
  endif()
  message(STATUS "streamcvd: Python module skipped (pybind11, Python headers or numpy not found)")
  return()
endif()
message(STATUS "streamcvd: Python module for ${Python_EXECUTABLE} (${Python_VERSION})")
add_subdirectory(python)
