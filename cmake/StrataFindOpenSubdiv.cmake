# Locates OpenSubdiv without its CMake package: Debian 12's
# OpenSubdivConfig.cmake names static libraries that are not shipped, and
# there is no pkg-config file.  Defines the imported target
# StrataDeps::OpenSubdiv (osdCPU: Far, Sdc, Vtr and the CPU evaluators).
# Installed next to StrataConfig.cmake so consumers find it the same way.
if(NOT TARGET StrataDeps::OpenSubdiv)
  find_path(STRATA_OSD_INCLUDE_DIR opensubdiv/far/topologyRefiner.h)
  find_library(STRATA_OSD_CPU_LIBRARY NAMES osdCPU)
  if(NOT STRATA_OSD_INCLUDE_DIR OR NOT STRATA_OSD_CPU_LIBRARY)
    message(FATAL_ERROR "OpenSubdiv not found (Debian: apt-get install libosd-dev, or run cmake/install-deps.sh)")
  endif()
  add_library(StrataDeps::OpenSubdiv UNKNOWN IMPORTED)
  set_target_properties(StrataDeps::OpenSubdiv PROPERTIES
    IMPORTED_LOCATION "${STRATA_OSD_CPU_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${STRATA_OSD_INCLUDE_DIR}")
endif()
