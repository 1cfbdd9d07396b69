# Debian packages with CPack (deploy/package.sh configures with -DCMAKE_INSTALL_PREFIX=/usr and runs
# cpack): one .deb per install component.
#
#   lipsyncd                lipsyncd, lipsync, the data, the docs, the systemd unit, /etc/lipsyncd
#   lipsync-client-dev      headers, static libraries, CMake package, pkg-config file, the .proto
#   python3-lipsync-client  lipsync_client and its generated stubs (architecture all)
#
# The server's shared-library dependencies come from dpkg-shlibdeps; the two others name the
# Debian 12 packages their users compile or run against.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME lipsyncd)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "lipsyncd maintainers <lipsyncd@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "coarticulated lip-sync animation server")
set(CPACK_PACKAGING_INSTALL_PREFIX ${CMAKE_INSTALL_PREFIX})
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL server)
if(LIPSYNC_BUILD_CLIENT)
  list(APPEND CPACK_COMPONENTS_ALL dev)
endif()
if(LIPSYNC_BUILD_PYTHON)
  list(APPEND CPACK_COMPONENTS_ALL python)
endif()
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_PACKAGE_HOMEPAGE "https://github.com/lipsyncd/lipsyncd")

set(CPACK_DEBIAN_SERVER_PACKAGE_NAME lipsyncd)
set(CPACK_DEBIAN_SERVER_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_SERVER_PACKAGE_SECTION net)
set(CPACK_COMPONENT_SERVER_DESCRIPTION
  "coarticulated lip-sync animation server (gRPC)\n lipsyncd turns timed phoneme streams into facial animation; lipsync is its command line.")
# The config file under /etc is a conffile (kept across upgrades when edited).
if(CMAKE_INSTALL_PREFIX STREQUAL "/usr")
  file(WRITE ${PROJECT_BINARY_DIR}/cmake/debian-server/conffiles "/etc/lipsyncd/lipsyncd.json\n")
  set(CPACK_DEBIAN_SERVER_PACKAGE_CONTROL_EXTRA ${PROJECT_BINARY_DIR}/cmake/debian-server/conffiles)
endif()

set(CPACK_DEBIAN_DEV_PACKAGE_NAME lipsync-client-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS
  "libgrpc++-dev (>= 1.51), libprotobuf-dev (>= 3.21), nlohmann-json3-dev (>= 3.10), pkg-config | pkgconf")
set(CPACK_COMPONENT_DEV_DESCRIPTION
  "C++ client library of lipsyncd\n Headers, static libraries, find_package(lipsync) and lipsync-client.pc.")

set(CPACK_DEBIAN_PYTHON_PACKAGE_NAME python3-lipsync-client)
set(CPACK_DEBIAN_PYTHON_PACKAGE_ARCHITECTURE all)
set(CPACK_DEBIAN_PYTHON_PACKAGE_SECTION python)
set(CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS "python3 (>= 3.9), python3-grpcio (>= 1.51), python3-protobuf (>= 3.21)")
set(CPACK_COMPONENT_PYTHON_DESCRIPTION
  "Python client of lipsyncd\n The lipsync_client package with the generated lipsync.v1 gRPC stubs.")

include(CPack)
