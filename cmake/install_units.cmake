# sirad: installs the systemd units (`cmake --install`, from CMakeLists.txt's install(SCRIPT)),
# naming the programs by their path under the prefix given at install time, not at configure
# time. Set before it: SIRAD_SOURCE_DIR, SIRAD_UNIT_DIR and SIRAD_BINDIR_REL (relative to the
# prefix, or absolute). DESTDIR is honoured for staged installs.
foreach(var SIRAD_UNIT_DIR SIRAD_BINDIR_REL)
  if(IS_ABSOLUTE "${${var}}")
    set(${var}_FULL "${${var}}")
  else()
    set(${var}_FULL "${CMAKE_INSTALL_PREFIX}/${${var}}")
  endif()
endforeach()
set(SIRAD_BINDIR "${SIRAD_BINDIR_REL_FULL}")
foreach(unit sirad-node.service sirad-coordinator@.service sirad-farm.service)
  set(target "$ENV{DESTDIR}${SIRAD_UNIT_DIR_FULL}/${unit}")
  message(STATUS "Installing: ${target}")
  configure_file("${SIRAD_SOURCE_DIR}/deploy/systemd/${unit}.in" "${target}" @ONLY)
  list(APPEND CMAKE_INSTALL_MANIFEST_FILES "${target}")
endforeach()
