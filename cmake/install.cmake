# Install rules: `cmake --install build --prefix DIR` puts everything under DIR.
#
#   bin/lipsyncd, bin/lipsync, bin/lipsync-loadtest component server (Debian package lipsyncd)
#   share/lipsync/data/, share/lipsync/web/,
#   share/doc/lipsyncd/                            component server
#   lib/systemd/system/lipsyncd.service,
#   etc/lipsyncd/lipsyncd.json (/etc with prefix /usr)  component server
#   include/lipsync/..., lib/liblipsync_*.a,
#   lib/cmake/lipsync/lipsyncConfig.cmake,
#   lib/pkgconfig/lipsync-client.pc                component dev (lipsync-client-dev)
#   lib/python3/dist-packages/{lipsync_client,lipsync}  component python (python3-lipsync-client)
#
# Consumers: find_package(lipsync CONFIG) + target_link_libraries(app PRIVATE lipsync::client),
# or `pkg-config --cflags --libs lipsync-client` (the headers need C++20).
include(CMakePackageConfigHelpers)

set(LIPSYNC_CMAKE_INSTALL_DIR "${CMAKE_INSTALL_LIBDIR}/cmake/lipsync")
set(LIPSYNC_PYTHON_INSTALL_DIR "lib/python3/dist-packages" CACHE STRING
  "Where the Python client is installed, relative to the prefix (Debian's layout)")
# The configuration file belongs in /etc for a system install, under the prefix otherwise
# (so that `cmake --install --prefix DIR` never writes outside DIR).
if(CMAKE_INSTALL_PREFIX STREQUAL "/usr")
  set(LIPSYNC_CONFIG_INSTALL_DIR "/etc/lipsyncd")
else()
  set(LIPSYNC_CONFIG_INSTALL_DIR "${CMAKE_INSTALL_SYSCONFDIR}/lipsyncd")
endif()

# --- the programs, the data, the documentation, the service ---------------------------------
if(TARGET lipsync)
  install(TARGETS lipsync RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT server)
endif()
if(TARGET lipsync-loadtest)
  install(TARGETS lipsync-loadtest RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT server)
endif()
if(LIPSYNC_BUILD_SERVER)
  install(TARGETS lipsyncd RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT server)
  install(FILES deploy/systemd/lipsyncd.service DESTINATION lib/systemd/system COMPONENT server)
  install(FILES deploy/systemd/lipsyncd.json DESTINATION ${LIPSYNC_CONFIG_INSTALL_DIR} COMPONENT server)
  # The browser viewer's page (lipsyncd serves its embedded copy; these are for reading and reuse).
  install(DIRECTORY server/web/ DESTINATION ${CMAKE_INSTALL_DATADIR}/lipsync/web COMPONENT server)
endif()
# The binaries embed the model, the phone sets and the face; the files are installed as the
# starting point of models of one's own (--model NAME=FILE) and for their licences.
install(DIRECTORY data/ DESTINATION ${CMAKE_INSTALL_DATADIR}/lipsync/data COMPONENT server)
install(DIRECTORY docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT server)
install(FILES README.md DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT server)
# The Godot add-on (docs/integrations.md): copied into a Godot project's addons/ folder.
install(DIRECTORY clients/godot/addons/lipsync DESTINATION ${CMAKE_INSTALL_DATADIR}/lipsync/godot/addons
        COMPONENT server)
install(FILES proto/lipsync/v1/lipsync.proto DESTINATION ${CMAKE_INSTALL_DATADIR}/lipsync/proto/lipsync/v1
        COMPONENT dev)

# --- the C++ client library: headers, static libraries, CMake package, pkg-config ---------------
if(LIPSYNC_BUILD_CLIENT)
  set(_lipsync_face_target "")
  if(TARGET lipsync_face)
    set(_lipsync_face_target lipsync_face)
  endif()
  install(TARGETS lipsync_core ${_lipsync_face_target} lipsync_proto lipsync_client EXPORT lipsyncTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
          INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  set(_lipsync_without_face "")
  if(NOT LIPSYNC_BUILD_FACE)
    set(_lipsync_without_face PATTERN face EXCLUDE)
  endif()
  install(DIRECTORY core/include/lipsync clients/lib/include/lipsync
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT dev ${_lipsync_without_face})
  install(FILES ${PROJECT_BINARY_DIR}/proto/lipsync/v1/lipsync.pb.h
                ${PROJECT_BINARY_DIR}/proto/lipsync/v1/lipsync.grpc.pb.h
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/lipsync/v1 COMPONENT dev)
  install(EXPORT lipsyncTargets NAMESPACE lipsync:: DESTINATION ${LIPSYNC_CMAKE_INSTALL_DIR} COMPONENT dev)
  configure_package_config_file(cmake/lipsyncConfig.cmake.in
    ${PROJECT_BINARY_DIR}/cmake/lipsyncConfig.cmake INSTALL_DESTINATION ${LIPSYNC_CMAKE_INSTALL_DIR})
  write_basic_package_version_file(${PROJECT_BINARY_DIR}/cmake/lipsyncConfigVersion.cmake
    VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
  install(FILES ${PROJECT_BINARY_DIR}/cmake/lipsyncConfig.cmake ${PROJECT_BINARY_DIR}/cmake/lipsyncConfigVersion.cmake
          DESTINATION ${LIPSYNC_CMAKE_INSTALL_DIR} COMPONENT dev)
  # Relocatable: the prefix is found from the .pc file's own place (${pcfiledir}).
  file(RELATIVE_PATH LIPSYNC_PC_TO_PREFIX "/prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/prefix")
  configure_file(cmake/lipsync-client.pc.in ${PROJECT_BINARY_DIR}/cmake/lipsync-client.pc @ONLY)
  install(FILES ${PROJECT_BINARY_DIR}/cmake/lipsync-client.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig
          COMPONENT dev)
endif()

# --- the Python client with its generated stubs -------------------------------------------------
if(LIPSYNC_BUILD_PYTHON)
  install(DIRECTORY clients/python/lipsync_client DESTINATION ${LIPSYNC_PYTHON_INSTALL_DIR} COMPONENT python
          PATTERN __pycache__ EXCLUDE)
  install(DIRECTORY ${LIPSYNC_PYTHON_STUBS_DIR}/lipsync DESTINATION ${LIPSYNC_PYTHON_INSTALL_DIR}
          COMPONENT python PATTERN __pycache__ EXCLUDE)
endif()
