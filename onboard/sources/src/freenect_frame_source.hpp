#pragma once
// Kinect v1 through libfreenect (private to hq_sources; use open_camera_source("freenect:N")).

#include "hq/sources/camera_sources.hpp"

#include <memory>

namespace hq::sources::detail {

/// Opens the Kinect at `index`; throws hq::InputError naming it when it is absent, the mode is
/// not offered, or (under fakenect) the dump is missing or corrupt.
std::unique_ptr<CameraSource> open_freenect(int index, const CameraSourceOptions& options);

}  // namespace hq::sources::detail
