#pragma once
// OpenNI2 devices and .oni files (private to hq_sources; use open_camera_source("openni2:URI")).

#include "hq/sources/camera_sources.hpp"

#include <memory>
#include <string>

namespace hq::sources::detail {

/// Opens the OpenNI2 device or .oni file at `uri` (empty = any device); throws hq::InputError
/// naming the URI when it is absent, the file is unreadable or a mode is not offered.
std::unique_ptr<CameraSource> open_openni2(const std::string& uri,
                                           const CameraSourceOptions& options);

}  // namespace hq::sources::detail
