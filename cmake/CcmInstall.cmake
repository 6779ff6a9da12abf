# `cmake --install` and the Debian packages (CPack DEB, one package per component):
#   ccm-common  QoS profiles, the vocabulary, the editable /etc/ccm-slam-dds/wifi.xml and
#               wifi-secure.xml (conffiles), the discovery server script
#   ccm-agent   ccm_agent, the onboard config template, ccm-agent@.service
#   ccm-server  ccm_server, ccm_ctl, server.yaml (conffile), ccm-server.service
#   ccm-tools   ccm_sim, ccm_eval, ccm_vocab, ccm_replay
# Binaries find their data at <bindir>/../share/ccm-slam-dds (slam_core/common/install_paths.h),
# so any prefix works. Run-time library dependencies come from dpkg-shlibdeps.
include(GNUInstallDirs)
set(CCM_DATA_INSTALL_DIR share/ccm-slam-dds)  # must match rt::kInstallDataSubdir

install(FILES qos_profiles/default.xml qos_profiles/wifi.xml qos_profiles/secure.xml
        DESTINATION ${CCM_DATA_INSTALL_DIR}/qos_profiles COMPONENT common)
if(DEFINED CCM_DEFAULT_VOCAB_FILE)
  install(FILES ${CCM_DEFAULT_VOCAB_FILE} DESTINATION ${CCM_DATA_INSTALL_DIR}/vocabulary COMPONENT common)
endif()
install(FILES docs/deployment.md docs/troubleshooting.md DESTINATION share/doc/ccm-slam-dds COMPONENT common)

# Templates with install paths filled in at install time (cmake/ccm_install_template.cmake).
function(ccm_install_template src dest name component)
  if(NOT IS_ABSOLUTE "${src}")
    set(src "${PROJECT_SOURCE_DIR}/${src}")
  endif()
  install(CODE "set(CCM_TEMPLATE \"${src}\")
set(CCM_TEMPLATE_DEST \"${dest}\")
set(CCM_TEMPLATE_DEST_SUBDIR \"${dest}\")
set(CCM_TEMPLATE_NAME \"${name}\")
set(CCM_TEMPLATE_STAGING \"${CMAKE_BINARY_DIR}/install-templates/${component}\")
include(\"${PROJECT_SOURCE_DIR}/cmake/ccm_install_template.cmake\")" COMPONENT ${component})
endfunction()
# A verbatim copy operators edit (peer addresses, discovery server address).
ccm_install_template(qos_profiles/wifi.xml etc wifi.xml common)
# What the packaged configs use (secure by default): wifi.xml with datagrams that carry the
# DDS-Security handshake (docs/security.md "Wi-Fi: the handshake needs 8 kB datagrams").
set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS qos_profiles/wifi.xml)
file(READ qos_profiles/wifi.xml CCM_WIFI_XML)
string(REPLACE "<maxMessageSize>1400</maxMessageSize>" "<maxMessageSize>8192</maxMessageSize>" CCM_WIFI_SECURE_XML
       "${CCM_WIFI_XML}")
if(CCM_WIFI_SECURE_XML STREQUAL CCM_WIFI_XML)
  message(FATAL_ERROR "qos_profiles/wifi.xml: no <maxMessageSize>1400</maxMessageSize> to raise for wifi-secure.xml")
endif()
string(REPLACE "<!-- wifi.xml: lossy WiFi links. Unicast discovery via initial peers, 1400 B datagrams," "<!-- wifi-secure.xml (made from wifi.xml at build time: the same but 8192 B datagrams, which carry the DDS-Security handshake): lossy WiFi links. Unicast discovery via initial peers,"
       CCM_WIFI_SECURE_XML "${CCM_WIFI_SECURE_XML}")
file(CONFIGURE OUTPUT ${CMAKE_BINARY_DIR}/qos_profiles/wifi-secure.xml CONTENT "${CCM_WIFI_SECURE_XML}" @ONLY)
ccm_install_template(${CMAKE_BINARY_DIR}/qos_profiles/wifi-secure.xml etc wifi-secure.xml common)
install(PROGRAMS deploy/run-discovery-server.sh DESTINATION ${CCM_DATA_INSTALL_DIR}/scripts COMPONENT common)
install(PROGRAMS deploy/security/make-pki.sh DESTINATION ${CCM_DATA_INSTALL_DIR}/scripts COMPONENT common)

if(CCM_BUILD_RUNTIMES)
  install(TARGETS ccm_agent RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT agent)
  install(FILES deploy/config/agent-onboard.yaml DESTINATION ${CCM_DATA_INSTALL_DIR}/config COMPONENT agent)
  ccm_install_template(deploy/systemd/ccm-agent@.service.in systemd ccm-agent@.service agent)
  if(NOT CCM_AGENT_ONLY)
    install(TARGETS ccm_server ccm_ctl RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT server)
    ccm_install_template(deploy/config/server-daemon.yaml.in etc server.yaml server)
    ccm_install_template(deploy/systemd/ccm-server.service.in systemd ccm-server.service server)
    # The live map view page (docs/map-view.md); ccm_server/ccm_replay find it beside themselves.
    install(DIRECTORY server_runtime/web/ DESTINATION ${CCM_DATA_INSTALL_DIR}/web COMPONENT common)
  endif()
endif()
if(NOT CCM_AGENT_ONLY)
  install(TARGETS ccm_sim_cli ccm_eval_cli ccm_vocab ccm_replay RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
          COMPONENT tools)
endif()

# --- Debian packages: `cpack -G DEB` in the build directory (deploy/build-packages.sh).
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME ccm-slam-dds)
set(CPACK_PACKAGE_VENDOR "ccm-slam-dds")
set(CPACK_PACKAGE_CONTACT "ccm-slam-dds maintainers <ccm-slam-dds@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "Centralized collaborative monocular SLAM for robot teams on Fast DDS")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
# Install with DESTDIR under prefix /usr, so /etc/ccm-slam-dds and the unit paths are the
# final ones (the templates above compute them from the prefix).
set(CPACK_SET_DESTDIR ON)
set(CPACK_INSTALL_PREFIX /usr)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_ENABLE_COMPONENT_DEPENDS ON)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_COMPONENTS_ALL common agent)
if(NOT CCM_AGENT_ONLY)
  list(APPEND CPACK_COMPONENTS_ALL server tools)
endif()
set(CPACK_DEBIAN_COMMON_PACKAGE_NAME ccm-common)
set(CPACK_DEBIAN_AGENT_PACKAGE_NAME ccm-agent)
set(CPACK_DEBIAN_SERVER_PACKAGE_NAME ccm-server)
set(CPACK_DEBIAN_TOOLS_PACKAGE_NAME ccm-tools)
set(CPACK_COMPONENT_COMMON_DESCRIPTION "ccm-slam-dds shared data: QoS profiles, vocabulary, example network configs")
set(CPACK_COMPONENT_AGENT_DESCRIPTION "ccm-slam-dds onboard agent (monocular VO, DDS link to the server)")
set(CPACK_COMPONENT_SERVER_DESCRIPTION "ccm-slam-dds ground-station server daemon and ccm_ctl")
set(CPACK_COMPONENT_TOOLS_DESCRIPTION "ccm-slam-dds tools: simulator, evaluation, vocabulary, replay")
set(CPACK_COMPONENT_AGENT_DEPENDS common)
set(CPACK_COMPONENT_SERVER_DEPENDS common)
set(CPACK_COMPONENT_TOOLS_DEPENDS common)
# The discovery server script needs `fastdds` (Debian: fastdds-tools).
set(CPACK_DEBIAN_COMMON_PACKAGE_SUGGESTS "fastdds-tools")
# The live map view serves three.js from Debian's libjs-three.
set(CPACK_DEBIAN_SERVER_PACKAGE_RECOMMENDS "libjs-three")
# Operators edit these; dpkg keeps their changes on upgrade.
file(WRITE ${CMAKE_BINARY_DIR}/deb-control/common/conffiles "/etc/ccm-slam-dds/wifi.xml\n/etc/ccm-slam-dds/wifi-secure.xml\n")
file(WRITE ${CMAKE_BINARY_DIR}/deb-control/server/conffiles "/etc/ccm-slam-dds/server.yaml\n")
set(CPACK_DEBIAN_COMMON_PACKAGE_CONTROL_EXTRA ${CMAKE_BINARY_DIR}/deb-control/common/conffiles)
set(CPACK_DEBIAN_SERVER_PACKAGE_CONTROL_EXTRA ${CMAKE_BINARY_DIR}/deb-control/server/conffiles)
if(CMAKE_CROSSCOMPILING AND CCM_ARM64_SYSROOT)
  # arm64 cross build against a sysroot (cmake/toolchain-aarch64-sysroot.cmake): dpkg-shlibdeps
  # looks for the libraries in the sysroot (/lib first: merged /usr, libc6 lists /lib/...), reads
  # their packages' symbols/shlibs from the sysroot's dpkg database, with arm64's objdump, and
  # asks dpkg-query through deploy/cross-shlibdeps/dpkg-query (which strips the sysroot prefix).
  # The environment is set inside cpack, so a plain `cpack -G DEB` in the build tree works.
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS_PRIVATE_DIRS
      ${CCM_ARM64_SYSROOT}/lib/aarch64-linux-gnu ${CCM_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu)
  file(WRITE ${CMAKE_BINARY_DIR}/cpack-cross-env.cmake
       "set(ENV{DEB_HOST_ARCH} arm64)\n"
       "set(ENV{DPKG_ADMINDIR} \"${CCM_ARM64_SYSROOT}/var/lib/dpkg\")\n"
       "set(ENV{CCM_ARM64_SYSROOT} \"${CCM_ARM64_SYSROOT}\")\n"
       "set(ENV{PATH} \"${PROJECT_SOURCE_DIR}/deploy/cross-shlibdeps:\$ENV{PATH}\")\n")
  set(CPACK_PROJECT_CONFIG_FILE ${CMAKE_BINARY_DIR}/cpack-cross-env.cmake)
endif()
include(CPack)
