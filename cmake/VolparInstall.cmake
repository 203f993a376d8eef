# Install and export rules: `cmake --install <build> --prefix <prefix>` puts the libraries, their headers
# under <prefix>/include/volpar/ and a package configuration under <prefix>/lib/cmake/volpar/, so that a
# project outside this tree can say
#
#   find_package(volpar 0.1 REQUIRED)
#   target_link_libraries(app PRIVATE volpar::volpar)
#
# (docs/api.md). The public headers use Eigen and the standard library only; yaml-cpp and HDF5 are the
# engine library's private dependencies, found again by the package configuration because the libraries
# are static. FCL (collision/reference/) is the tests' and `volpar check`'s referee and is not installed.
include(CMakePackageConfigHelpers)

set_target_properties(volpar_core PROPERTIES EXPORT_NAME core)
set_target_properties(volpar_collision PROPERTIES EXPORT_NAME collision)
set_target_properties(volpar_dynamics PROPERTIES EXPORT_NAME dynamics)
set_target_properties(volpar_engine PROPERTIES EXPORT_NAME engine)
# volpar::volpar: everything an embedding program needs (the engine and the modules below it)
add_library(volpar_library INTERFACE)
set_target_properties(volpar_library PROPERTIES EXPORT_NAME volpar)
target_link_libraries(volpar_library INTERFACE volpar_engine)
add_library(volpar::volpar ALIAS volpar_library)

install(TARGETS volpar_core volpar_collision volpar_dynamics volpar_engine volpar_library
        EXPORT volparTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS volpar RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# the plots of a trajectory (matplotlib): volpar-plot TRAJ.h5
install(PROGRAMS ${PROJECT_SOURCE_DIR}/tools/scripts/volpar_plot.py DESTINATION ${CMAKE_INSTALL_BINDIR} RENAME volpar-plot)
foreach(module engine collision dynamics)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${module}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/volpar/${module}
          FILES_MATCHING PATTERN "*.hpp" PATTERN "reference" EXCLUDE)
endforeach()
install(FILES ${PROJECT_BINARY_DIR}/generated/volpar/engine/core/version.hpp
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/volpar/engine/core)

set(VOLPAR_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/volpar)
install(EXPORT volparTargets NAMESPACE volpar:: DESTINATION ${VOLPAR_CMAKE_DIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/volparConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/volparConfig.cmake INSTALL_DESTINATION ${VOLPAR_CMAKE_DIR})
# 0.x: a minor version may change the interface, so only the same minor version is compatible
write_basic_package_version_file(${PROJECT_BINARY_DIR}/volparConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/volparConfig.cmake ${PROJECT_BINARY_DIR}/volparConfigVersion.cmake
        DESTINATION ${VOLPAR_CMAKE_DIR})
