# `cmake --install`: the headers, the libraries, the program, the Python module and a CMake package
# (find_package(fluoro) with the targets fluoro::engine, fluoro::kernels, fluoro::mesh,
# fluoro::datasets, fluoro::pipelines, fluoro::sweep). docs/install.md.
#
# The libraries are static. The backends (fluoro::kernels) are named by a registry in the same
# library that lists them explicitly (kernels/backend_registry.hpp), so nothing a linker may drop
# from a static archive carries a registration.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(FLUORO_INSTALL_INCLUDEDIR ${CMAKE_INSTALL_INCLUDEDIR}/fluoro)
set(FLUORO_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/fluoro)

set(fluoro_export_targets fluoro_warnings fluoro_engine fluoro_kernels fluoro_mesh fluoro_datasets fluoro_pipelines
  fluoro_sweep)
if(FLUORO_WITH_VULKAN)
  list(APPEND fluoro_export_targets fluoro_shaders)  # header-only, needed by nothing installed
endif()
set_target_properties(fluoro_warnings PROPERTIES EXPORT_NAME base)
foreach(t engine kernels mesh datasets pipelines sweep)
  set_target_properties(fluoro_${t} PROPERTIES EXPORT_NAME ${t})
endforeach()

install(TARGETS ${fluoro_export_targets} EXPORT fluoroTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${FLUORO_INSTALL_INCLUDEDIR})
install(TARGETS fluoro RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The engine's modules (GDCM, HDF5: engine/plugin_loader.hpp), where it looks for them.
install(TARGETS fluoro_dicom fluoro_hdf5 LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/fluoro)
foreach(dir engine kernels datasets pipelines)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir}/ DESTINATION ${FLUORO_INSTALL_INCLUDEDIR}/${dir}
    FILES_MATCHING PATTERN "*.hpp")
endforeach()
install(FILES ${PROJECT_BINARY_DIR}/generated/engine/version.hpp DESTINATION ${FLUORO_INSTALL_INCLUDEDIR}/engine)
if(FLUORO_WITH_PYTHON)
  # Import it with PYTHONPATH=PREFIX/lib/fluoro/python.
  install(TARGETS fluoro_python LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/fluoro/python)
endif()

install(EXPORT fluoroTargets NAMESPACE fluoro:: FILE fluoroTargets.cmake DESTINATION ${FLUORO_INSTALL_CMAKEDIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/fluoroConfig.cmake.in
  ${PROJECT_BINARY_DIR}/fluoroConfig.cmake INSTALL_DESTINATION ${FLUORO_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/fluoroConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/fluoroConfig.cmake ${PROJECT_BINARY_DIR}/fluoroConfigVersion.cmake
  DESTINATION ${FLUORO_INSTALL_CMAKEDIR})

# The test: install into a temporary prefix, build tests/install_consumer against it, run it.
# Not under the sanitizers: the consumer would have to be built with them too.
if(FLUORO_BUILD_TESTS AND NOT FLUORO_SANITIZE)
  add_test(NAME Install.ConsumerBuildsAndRuns
    COMMAND ${CMAKE_COMMAND} -DBUILD_DIR=${PROJECT_BINARY_DIR}
            -DCONSUMER_DIR=${PROJECT_SOURCE_DIR}/tests/install_consumer
            -DWORK_DIR=${PROJECT_BINARY_DIR}/install_test
            -DGENERATOR=${CMAKE_GENERATOR}
            -DCXX_COMPILER=${CMAKE_CXX_COMPILER}
            -DCXX_LAUNCHER=${CMAKE_CXX_COMPILER_LAUNCHER}
            -DEXPECTED_VERSION=${PROJECT_VERSION}
            -DDICOM_FILE=${PROJECT_SOURCE_DIR}/fuzz/corpus/volume_dcm/ct_explicit.dcm
            -P ${PROJECT_SOURCE_DIR}/tests/install_consumer/run_install_test.cmake)
  set_tests_properties(Install.ConsumerBuildsAndRuns PROPERTIES TIMEOUT 600)
endif()
