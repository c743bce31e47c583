# Records the git revision at configure time for `gen4d info` and file attributes.
find_package(Git QUIET)
set(GEN4D_GIT_REVISION "unknown")
if(GIT_FOUND AND EXISTS ${CMAKE_SOURCE_DIR}/.git)
  execute_process(COMMAND ${GIT_EXECUTABLE} describe --always --dirty --abbrev=12
                  WORKING_DIRECTORY ${CMAKE_SOURCE_DIR}
                  OUTPUT_VARIABLE GEN4D_GIT_REVISION OUTPUT_STRIP_TRAILING_WHITESPACE
                  ERROR_QUIET)
  if(NOT GEN4D_GIT_REVISION)
    set(GEN4D_GIT_REVISION "unknown")
  endif()
endif()
