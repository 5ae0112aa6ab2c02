# `cmake --install build [--prefix P]` and `cpack` (three .deb files): the operator's programs in
# bin/ and the files they ship with under share/haptiquad/, in the repository's relative layout,
# where hq::config::resolve_data_path() finds them from the executable's own location.
#
# Debian packages (docs/development.md, "Packages"), one CPack component each:
#   haptiquad-vehicle  the companion computer: hq-onboard, hq-keys, hq-onboard.service and its
#                      files in /etc/haptiquad. No console, no simulator: nothing of SDL, ImGui
#                      or the simulator's renderer (tests/install/package_test.sh checks Depends
#                      and what the installed programs load).
#   haptiquad-station  the operator's laptop: hq-ground, hq-report, and the development tools
#                      that replay, evaluate or simulate (hq-sim, hq-sim-flight, hq-odometry,
#                      hq-record, hq-evaluate, hq-velocity-eval), with the simulator's worlds,
#                      flights and the ground's configs. The simulator lives here: a vehicle
#                      never runs it, a station runs it to rehearse and test.
#   haptiquad-data     architecture-independent files both read: config/, calib/, README and
#                      docs/ (so neither binary package owns a file the other needs).
# Each has /usr/share/doc/<package>/copyright (DEP-5) and changelog.Debian.gz; programs are
# stripped (Release builds carry no debug info, so a -dbgsym package would be empty: none is
# made); man pages from --help (help2man) and bash completions are generated at build time.

set(HQ_VEHICLE_PROGRAMS hq-onboard hq-keys)
set(HQ_STATION_PROGRAMS hq-ground hq-report hq-sim hq-sim-flight hq-odometry hq-record hq-evaluate
                        hq-velocity-eval)
set(HQ_PROGRAMS ${HQ_VEHICLE_PROGRAMS} ${HQ_STATION_PROGRAMS})
install(TARGETS ${HQ_VEHICLE_PROGRAMS} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT vehicle)
install(TARGETS ${HQ_STATION_PROGRAMS} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
        COMPONENT station)

set(HQ_DATA_DESTINATION ${CMAKE_INSTALL_DATADIR}/haptiquad)
set(HQ_DOC_ROOT ${CMAKE_INSTALL_DATADIR}/doc)
install(DIRECTORY config/ DESTINATION ${HQ_DATA_DESTINATION}/config COMPONENT data
        FILES_MATCHING PATTERN "*.yaml")
install(DIRECTORY calib/ DESTINATION ${HQ_DATA_DESTINATION}/calib COMPONENT data
        FILES_MATCHING PATTERN "*.yaml" PATTERN "test" EXCLUDE)
install(DIRECTORY onboard/sim/config/ DESTINATION ${HQ_DATA_DESTINATION}/onboard/sim/config
        COMPONENT station)
install(DIRECTORY onboard/sim/worlds/ DESTINATION ${HQ_DATA_DESTINATION}/onboard/sim/worlds
        COMPONENT station)
install(DIRECTORY onboard/closed_loop/flights/
        DESTINATION ${HQ_DATA_DESTINATION}/onboard/closed_loop/flights COMPONENT station)
install(DIRECTORY ground/config/ DESTINATION ${HQ_DATA_DESTINATION}/ground/config
        COMPONENT station)
install(FILES README.md DESTINATION ${HQ_DOC_ROOT}/haptiquad-data COMPONENT data)
install(DIRECTORY docs/ DESTINATION ${HQ_DOC_ROOT}/haptiquad-data/docs COMPONENT data
        FILES_MATCHING PATTERN "*.md")

# copyright and changelog.Debian.gz in each package's own doc folder (Debian policy 12.5, 12.7).
foreach(component vehicle station data)
  set(HQ_DEB_PACKAGE haptiquad-${component})
  configure_file(cmake/debian/changelog.in ${PROJECT_BINARY_DIR}/debian/${component}/changelog.Debian
                 @ONLY)
  execute_process(COMMAND gzip -9nf ${PROJECT_BINARY_DIR}/debian/${component}/changelog.Debian)
  install(FILES cmake/debian/copyright
                ${PROJECT_BINARY_DIR}/debian/${component}/changelog.Debian.gz
          DESTINATION ${HQ_DOC_ROOT}/${HQ_DEB_PACKAGE} COMPONENT ${component})
endforeach()

# Man pages and bash completions, generated from each program's --help once it is built.
find_program(HQ_HELP2MAN help2man)
if(NOT HQ_HELP2MAN)
  message(STATUS "help2man not found: no man pages (apt-get install help2man); completions only")
endif()
set(HQ_DESCRIPTION_hq-onboard "the on-board velocity chain of HaptiQuad on a frame source")
set(HQ_DESCRIPTION_hq-keys "DDS Security keys for the HaptiQuad link")
set(HQ_DESCRIPTION_hq-ground "HaptiQuad ground station: haptic or keyboard teleoperation")
set(HQ_DESCRIPTION_hq-report "flight report of an hq-ground recording")
set(HQ_DESCRIPTION_hq-sim "HaptiQuad simulator: scripted flights and SITL flight controller")
set(HQ_DESCRIPTION_hq-sim-flight "the on-board chain flown in closed loop by the simulator")
set(HQ_DESCRIPTION_hq-odometry "dense RGB-D odometry over a TUM sequence or a camera")
set(HQ_DESCRIPTION_hq-record "record a live RGB-D camera in the TUM RGB-D layout")
set(HQ_DESCRIPTION_hq-evaluate "relative pose and absolute trajectory error of a trajectory")
set(HQ_DESCRIPTION_hq-velocity-eval "camera velocity of the core paper against ground truth")
set(HQ_PROGRAM_DOCS)
foreach(program ${HQ_PROGRAMS})
  set(man ${PROJECT_BINARY_DIR}/man/${program}.1.gz)
  set(completion ${PROJECT_BINARY_DIR}/completions/${program})
  set(outputs ${completion})
  if(HQ_HELP2MAN)
    list(APPEND outputs ${man})
  endif()
  add_custom_command(
    OUTPUT ${outputs}
    COMMAND bash ${PROJECT_SOURCE_DIR}/cmake/hq-program-docs.sh $<TARGET_FILE:${program}>
            "${HQ_DESCRIPTION_${program}}" ${PROJECT_BINARY_DIR}/man ${PROJECT_BINARY_DIR}/completions
    DEPENDS ${program} ${PROJECT_SOURCE_DIR}/cmake/hq-program-docs.sh
    COMMENT "man page and completion of ${program}" VERBATIM)
  list(APPEND HQ_PROGRAM_DOCS ${outputs})
  if(program IN_LIST HQ_VEHICLE_PROGRAMS)
    set(component vehicle)
  else()
    set(component station)
  endif()
  if(HQ_HELP2MAN)
    install(FILES ${man} DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT ${component})
  endif()
  install(FILES ${completion} DESTINATION ${CMAKE_INSTALL_DATADIR}/bash-completion/completions
          COMPONENT ${component})
endforeach()
add_custom_target(hq_program_docs ALL DEPENDS ${HQ_PROGRAM_DOCS})

# hq-onboard as a service of the companion computer: its unit, EnvironmentFile, config and
# vehicle file in /etc/haptiquad, and its user. Where depends on the prefix, known only at
# install time: HqInstallService.cmake says where and why.
install(CODE "set(HQ_SERVICE_SOURCE_DIR \"${PROJECT_SOURCE_DIR}/onboard/apps/service\")
set(HQ_SHIPPED_SOURCE_DIR \"${PROJECT_SOURCE_DIR}\")
set(HQ_STAGING_DIR \"${PROJECT_BINARY_DIR}/service\")
set(HQ_BINDIR \"${CMAKE_INSTALL_BINDIR}\")
set(HQ_DOCDIR \"${HQ_DOC_ROOT}/haptiquad-data\")" COMPONENT vehicle)
install(SCRIPT cmake/HqInstallService.cmake COMPONENT vehicle)

set(CPACK_PACKAGE_NAME haptiquad)
set(CPACK_PACKAGE_VENDOR "HaptiQuad")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "Haptic and keyboard teleoperation of an indoor quadrotor with RGB-D velocity estimation")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_GENERATOR DEB)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL vehicle station data)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "HaptiQuad developers <haptiquad@localhost>")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
# The Debian libraries the programs link come from dpkg-shlibdeps, not a hand-kept list.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_DATA_PACKAGE_NAME haptiquad-data)
set(CPACK_DEBIAN_DATA_PACKAGE_ARCHITECTURE all)
set(CPACK_COMPONENT_DATA_DESCRIPTION
    "HaptiQuad's shared files\nThe on-board config, camera and vehicle files, README and docs, read "
    "by both the vehicle and the station packages.")
set(CPACK_DEBIAN_VEHICLE_PACKAGE_NAME haptiquad-vehicle)
set(CPACK_DEBIAN_VEHICLE_PACKAGE_DEPENDS "haptiquad-data (= ${PROJECT_VERSION})")
set(CPACK_COMPONENT_VEHICLE_DESCRIPTION
    "HaptiQuad on the vehicle's companion computer\nhq-onboard (the on-board velocity chain, "
    "MAVLink to the flight controller, the DDS link) as a systemd service, and hq-keys.")
set(CPACK_DEBIAN_STATION_PACKAGE_NAME haptiquad-station)
set(CPACK_DEBIAN_STATION_PACKAGE_DEPENDS "haptiquad-data (= ${PROJECT_VERSION})")
# hq-report draws its plots with gnuplot (spawned, not linked), so dpkg-shlibdeps cannot see it.
set(CPACK_DEBIAN_STATION_PACKAGE_RECOMMENDS "gnuplot-nox | gnuplot")
set(CPACK_COMPONENT_STATION_DESCRIPTION
    "HaptiQuad ground station and tools\nhq-ground (haptic or keyboard teleoperation, the console, "
    "recording and replay), hq-report, the simulator (hq-sim, hq-sim-flight) and the "
    "evaluation tools.")
# The operator's files in /etc are conffiles (an edited one survives upgrades); postinst makes
# the service's user and its keys folder. The service is not enabled: a companion computer
# may be a development machine (docs/vehicle-integration.md, "Boot into it").
file(WRITE ${PROJECT_BINARY_DIR}/debian/conffiles
     "/etc/haptiquad/onboard.env\n/etc/haptiquad/onboard.yaml\n/etc/haptiquad/vehicle.yaml\n")
set(CPACK_DEBIAN_VEHICLE_PACKAGE_CONTROL_EXTRA
    ${PROJECT_BINARY_DIR}/debian/conffiles ${PROJECT_SOURCE_DIR}/cmake/debian/postinst)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
include(CPack)
