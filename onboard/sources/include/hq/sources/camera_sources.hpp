#pragma once
/// Live RGB-D cameras as frame sources: an ASUS Xtion Pro Live (or any OpenNI2 device or .oni
/// file) through OpenNI2, a Kinect v1 through libfreenect. Each kind is compiled in only when
/// CMake found its library; available_camera_sources() lists the kinds this build has.
///
/// Spec strings, as on the command line (`--source <spec>`):
///   openni2            first OpenNI2 device        openni2:<uri>   that device or .oni file
///   freenect           Kinect at index 0           freenect:<n>    Kinect at index n

#include "hq/frame_source/frame_source.hpp"
#include "hq/recording/tum_io.hpp"

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hq::sources {

/// Stream settings shared by the camera sources. Both streams use the same mode.
struct CameraSourceOptions {
  int width = 640;
  int height = 480;
  int fps = 30;
  /// Camera file (calib/ layout) used instead of the device's intrinsics; empty = the device's
  /// own (OpenNI2 reports its field of view) or, for libfreenect, which reports none,
  /// calib/kinect_v1.yaml relative to the current directory.
  std::string camera_file;
  /// No synchronised frame pair for this long counts as a lost device.
  std::int64_t frame_timeout_ns = 2'000'000'000;
  /// After a loss, next() tries to reopen the device at most this often.
  std::int64_t retry_interval_ns = 1'000'000'000;
};

/// A live camera: a FrameSource whose next() returns kNoFrame with error() set when the device
/// is missing or lost, and reopens it on later calls without restarting the process.
class CameraSource : public FrameSource {
 public:
  /// True while the device is open and delivering.
  [[nodiscard]] virtual bool connected() const = 0;
};

/// A parsed spec: kind "openni2" or "freenect", address = what follows the first ':' (may be
/// empty).
struct CameraSpec {
  std::string kind;
  std::string address;
};

/// Parses "openni2[:uri]" or "freenect[:index]". Throws hq::InputError naming the spec for an
/// unknown kind, a kind not compiled into this build, or a freenect index that is not a
/// non-negative integer.
CameraSpec parse_camera_spec(const std::string& spec);

/// The camera kinds compiled into this build ("openni2", "freenect"), possibly none.
std::vector<std::string> available_camera_sources();

/// Opens a camera. Throws hq::InputError with a clear message naming the spec, URI or index
/// when the spec is malformed, the options are out of range, the device is absent, or it does
/// not offer the requested mode. Once open, device loss is reported by next(), not thrown.
std::unique_ptr<CameraSource> open_camera_source(const std::string& spec,
                                                 const CameraSourceOptions& options);

}  // namespace hq::sources
