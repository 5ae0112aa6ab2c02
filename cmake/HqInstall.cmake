# `cmake --install build [--prefix P]` and `cpack` (a .deb): the operator's programs in bin/ and
# the files they ship with under share/haptiquad/, in the repository's relative layout, where
# hq::config::resolve_data_path() finds them from the executable's own location.

set(HQ_PROGRAMS hq-onboard hq-sim-flight hq-ground hq-sim hq-report hq-odometry hq-record hq-evaluate
                hq-velocity-eval hq-keys)
install(TARGETS ${HQ_PROGRAMS} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

set(HQ_DATA_DESTINATION ${CMAKE_INSTALL_DATADIR}/haptiquad)
install(DIRECTORY config/ DESTINATION ${HQ_DATA_DESTINATION}/config FILES_MATCHING PATTERN "*.yaml")
install(DIRECTORY calib/ DESTINATION ${HQ_DATA_DESTINATION}/calib
        FILES_MATCHING PATTERN "*.yaml" PATTERN "test" EXCLUDE)
install(DIRECTORY onboard/sim/config/ DESTINATION ${HQ_DATA_DESTINATION}/onboard/sim/config)
install(DIRECTORY onboard/sim/worlds/ DESTINATION ${HQ_DATA_DESTINATION}/onboard/sim/worlds)
install(DIRECTORY onboard/closed_loop/flights/
        DESTINATION ${HQ_DATA_DESTINATION}/onboard/closed_loop/flights)
install(DIRECTORY ground/config/ DESTINATION ${HQ_DATA_DESTINATION}/ground/config)
install(FILES README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}/docs FILES_MATCHING PATTERN "*.md")

# hq-onboard as a service of the companion computer: its unit, EnvironmentFile, config and
# vehicle file in /etc/haptiquad, and its user. Where depends on the prefix, known only at
# install time: HqInstallService.cmake says where and why.
install(CODE "set(HQ_SERVICE_SOURCE_DIR \"${PROJECT_SOURCE_DIR}/onboard/apps/service\")
set(HQ_SHIPPED_SOURCE_DIR \"${PROJECT_SOURCE_DIR}\")
set(HQ_STAGING_DIR \"${PROJECT_BINARY_DIR}/service\")
set(HQ_BINDIR \"${CMAKE_INSTALL_BINDIR}\")
set(HQ_DOCDIR \"${CMAKE_INSTALL_DOCDIR}\")")
install(SCRIPT cmake/HqInstallService.cmake)

set(CPACK_PACKAGE_NAME haptiquad)
set(CPACK_PACKAGE_VENDOR "HaptiQuad")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "Haptic and keyboard teleoperation of an indoor quadrotor with RGB-D velocity estimation")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_GENERATOR DEB)
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "HaptiQuad developers <haptiquad@localhost>")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
# The Debian libraries the programs link come from dpkg-shlibdeps, not a hand-kept list.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# hq-report draws its plots with gnuplot (spawned, not linked), so dpkg-shlibdeps cannot see it.
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "gnuplot-nox | gnuplot")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
# The operator's files in /etc are conffiles (an edited one survives upgrades); postinst makes
# the service's user and its keys folder. The service is not enabled: a companion computer
# may be a development machine (docs/vehicle-integration.md, "Boot into it").
file(WRITE ${PROJECT_BINARY_DIR}/debian/conffiles
     "/etc/haptiquad/onboard.env\n/etc/haptiquad/onboard.yaml\n/etc/haptiquad/vehicle.yaml\n")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${PROJECT_BINARY_DIR}/debian/conffiles ${PROJECT_SOURCE_DIR}/cmake/debian/postinst)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
include(CPack)
