# Runs at install time (install(CODE) from CcmInstall.cmake): copies the template
# CCM_TEMPLATE to CCM_TEMPLATE_DEST ("etc", "etc/agents" or "systemd") as CCM_TEMPLATE_NAME,
# replacing @CCM_BINDIR@, @CCM_CONFDIR@, @CCM_DATADIR@ and @CCM_DOCDIR@ with the final paths of THIS
# install. Configuration lives in /etc/ccm-slam-dds when the prefix is /usr (packages, GNU
# convention), else in <prefix>/etc/ccm-slam-dds. file(INSTALL) adds $DESTDIR itself.
if(CMAKE_INSTALL_PREFIX MATCHES "^/usr/?$")
  set(CCM_CONFDIR "/etc/ccm-slam-dds")
else()
  set(CCM_CONFDIR "${CMAKE_INSTALL_PREFIX}/etc/ccm-slam-dds")
endif()
set(CCM_BINDIR "${CMAKE_INSTALL_PREFIX}/bin")
set(CCM_DATADIR "${CMAKE_INSTALL_PREFIX}/share/ccm-slam-dds")
set(CCM_DOCDIR "${CMAKE_INSTALL_PREFIX}/share/doc/ccm-slam-dds")
if(CCM_TEMPLATE_DEST STREQUAL "systemd")
  set(dest "${CMAKE_INSTALL_PREFIX}/lib/systemd/system")
elseif(CCM_TEMPLATE_DEST STREQUAL "etc")
  set(dest "${CCM_CONFDIR}")
else()
  set(dest "${CCM_CONFDIR}/${CCM_TEMPLATE_DEST_SUBDIR}")
endif()
# One staging folder per install destination: cpack and a `cmake --install` may run at once.
string(MD5 install_id "$ENV{DESTDIR}|${CMAKE_INSTALL_PREFIX}")
set(staged "${CCM_TEMPLATE_STAGING}/${install_id}/${CCM_TEMPLATE_NAME}")
configure_file("${CCM_TEMPLATE}" "${staged}" @ONLY)
file(INSTALL "${staged}" DESTINATION "${dest}")
