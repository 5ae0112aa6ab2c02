# hq::warnings: the warning flags every target of ours links (PRIVATE), never a third-party one.
# Eigen, OpenCV, PCL, Cyclone come in through imported targets, whose include folders CMake passes
# as -isystem, so their headers' warnings do not count.
option(HQ_WERROR "Treat warnings as errors (on in CI)" OFF)
# -Wshadow and the conversion family, which the tree holds: on by default so that a local build
# warns where CI (HQ_WERROR) fails. One exemption, -Wsign-conversion in
# onboard/odometry/src/alignment.cpp, is set and counted in onboard/odometry/CMakeLists.txt.
option(HQ_STRICT_WARNINGS "Add -Wshadow and the conversion warnings" ON)
set(HQ_STRICT_WARNING_FLAGS -Wshadow -Wconversion -Wsign-conversion -Wdouble-promotion
    CACHE STRING "The flags HQ_STRICT_WARNINGS adds")

add_library(hq_warnings INTERFACE)
target_compile_options(hq_warnings INTERFACE -Wall -Wextra -Wpedantic)
if(HQ_STRICT_WARNINGS)
  target_compile_options(hq_warnings INTERFACE ${HQ_STRICT_WARNING_FLAGS})
endif()
if(HQ_WERROR)
  target_compile_options(hq_warnings INTERFACE -Werror)
endif()
add_library(hq::warnings ALIAS hq_warnings)
