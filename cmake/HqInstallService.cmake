# Runs at install time (install(SCRIPT) from HqInstall.cmake), when the prefix is known:
# `cmake --install --prefix P` and cpack's staging install (prefix /usr) alike. Installs
# hq-onboard.service, its EnvironmentFile, its config and vehicle file, and the sysusers.d entry
# of the user it runs as.
#
# Where: for the prefix /usr (the .deb), Debian 12's places, /lib/systemd/system for the unit
# (debhelper's and `pkg-config --variable=systemdsystemunitdir systemd`'s on bookworm) and
# /etc/haptiquad for what the operator edits, as GNUInstallDirs puts sysconfdir in /etc for
# /usr. Any other prefix keeps everything below it (<prefix>/lib/systemd/system,
# <prefix>/etc/haptiquad), so a test install writes nothing outside it; systemd reads
# /usr/local/lib/systemd/system too, other prefixes need `systemctl link`.
#
# Expects HQ_SERVICE_SOURCE_DIR, HQ_SHIPPED_SOURCE_DIR (the repository root), HQ_STAGING_DIR (a
# folder of the build tree), HQ_BINDIR, HQ_DOCDIR (relative to the prefix, GNUInstallDirs').

if(CMAKE_INSTALL_PREFIX STREQUAL "/usr")
  set(HQ_CONFIG_DIR /etc/haptiquad)
  set(unit_dir /lib/systemd/system)
else()
  set(HQ_CONFIG_DIR ${CMAKE_INSTALL_PREFIX}/etc/haptiquad)
  set(unit_dir ${CMAKE_INSTALL_PREFIX}/lib/systemd/system)
endif()
set(HQ_ONBOARD_EXE ${CMAKE_INSTALL_PREFIX}/${HQ_BINDIR}/hq-onboard)
set(HQ_DOC_DIR ${CMAKE_INSTALL_PREFIX}/${HQ_DOCDIR})

configure_file(${HQ_SERVICE_SOURCE_DIR}/hq-onboard.service.in
               ${HQ_STAGING_DIR}/hq-onboard.service @ONLY)
configure_file(${HQ_SERVICE_SOURCE_DIR}/onboard.env.in ${HQ_STAGING_DIR}/onboard.env @ONLY)
file(INSTALL ${HQ_STAGING_DIR}/hq-onboard.service DESTINATION ${unit_dir})
file(INSTALL ${HQ_SERVICE_SOURCE_DIR}/haptiquad.sysusers
     DESTINATION ${CMAKE_INSTALL_PREFIX}/lib/sysusers.d RENAME haptiquad.conf)

# What the operator edits is the shipped default until then. dpkg keeps an edited conffile on
# upgrade; `cmake --install` has no such notion, so it never overwrites one that exists.
set(config_files ${HQ_STAGING_DIR}/onboard.env ${HQ_SHIPPED_SOURCE_DIR}/config/onboard.yaml)
set(config_names onboard.env onboard.yaml)
list(APPEND config_files ${HQ_SHIPPED_SOURCE_DIR}/calib/vehicle_core_paper.yaml)
list(APPEND config_names vehicle.yaml)
foreach(file name IN ZIP_LISTS config_files config_names)
  if(EXISTS "$ENV{DESTDIR}${HQ_CONFIG_DIR}/${name}")
    message(STATUS "Kept (edited here): $ENV{DESTDIR}${HQ_CONFIG_DIR}/${name}")
  else()
    file(INSTALL ${file} DESTINATION ${HQ_CONFIG_DIR} RENAME ${name})
  endif()
endforeach()
