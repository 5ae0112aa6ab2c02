#include "hq/sources/camera_sources.hpp"

#include "hq/base/error.hpp"

#include "camera_common.hpp"

#include <cmath>

#ifdef HQ_HAVE_OPENNI2
#include "openni2_frame_source.hpp"
#endif
#ifdef HQ_HAVE_FREENECT
#include "freenect_frame_source.hpp"
#endif

namespace hq::sources {

namespace {

bool compiled_in(const std::string& kind) {
  for (const std::string& k : available_camera_sources()) {
    if (k == kind) return true;
  }
  return false;
}

std::string available_text() {
  std::string text;
  for (const std::string& k : available_camera_sources()) text += (text.empty() ? "" : ", ") + k;
  return text.empty() ? "none (neither OpenNI2 nor libfreenect was found at build time)" : text;
}

}  // namespace

CameraSpec parse_camera_spec(const std::string& spec) {
  const std::size_t colon = spec.find(':');
  CameraSpec parsed{spec.substr(0, colon),
                    colon == std::string::npos ? "" : spec.substr(colon + 1)};
  if (parsed.kind != "openni2" && parsed.kind != "freenect") {
    throw InputError("--source " + spec + ": unknown camera kind '" + parsed.kind +
                     "', expected openni2[:uri] or freenect[:index]");
  }
  if (!compiled_in(parsed.kind)) {
    throw InputError(
        "--source " + spec + ": this build has no " + parsed.kind +
        " support (its library was not found by CMake); available: " + available_text());
  }
  if (parsed.kind == "freenect" && !parsed.address.empty()) {
    const bool digits = parsed.address.size() <= 3 &&
                        parsed.address.find_first_not_of("0123456789") == std::string::npos;
    if (!digits) {
      throw InputError("--source " + spec + ": device index '" + parsed.address +
                       "', expected a non-negative integer such as freenect:0");
    }
  }
  return parsed;
}

std::vector<std::string> available_camera_sources() {
  std::vector<std::string> kinds;
#ifdef HQ_HAVE_OPENNI2
  kinds.emplace_back("openni2");
#endif
#ifdef HQ_HAVE_FREENECT
  kinds.emplace_back("freenect");
#endif
  return kinds;
}

std::unique_ptr<CameraSource> open_camera_source(const std::string& spec,
                                                 const CameraSourceOptions& options) {
  const CameraSpec parsed = parse_camera_spec(spec);
  detail::check_options(options, "--source " + spec);
#ifdef HQ_HAVE_OPENNI2
  if (parsed.kind == "openni2") return detail::open_openni2(parsed.address, options);
#endif
#ifdef HQ_HAVE_FREENECT
  if (parsed.kind == "freenect") {
    return detail::open_freenect(parsed.address.empty() ? 0 : std::stoi(parsed.address), options);
  }
#endif
  throw InputError("--source " + spec + ": not available in this build");
}

namespace detail {

void check_options(const CameraSourceOptions& options, const std::string& who) {
  auto require = [&](bool ok, const std::string& field, const std::string& value,
                     const char* expectation) {
    if (!ok) throw InputError(who + ": " + field + " = " + value + ", expected " + expectation);
  };
  require(options.width > 0 && options.width <= 4096, "width", std::to_string(options.width),
          "1..4096");
  require(options.height > 0 && options.height <= 4096, "height", std::to_string(options.height),
          "1..4096");
  require(options.fps > 0 && options.fps <= 240, "fps", std::to_string(options.fps), "1..240");
  require(options.frame_timeout_ns > 0, "frame_timeout_ns",
          std::to_string(options.frame_timeout_ns), "> 0");
  require(options.retry_interval_ns >= 0, "retry_interval_ns",
          std::to_string(options.retry_interval_ns), ">= 0");
}

config::CameraInfo load_camera_for(const CameraSourceOptions& options,
                                   const std::string& default_file, const std::string& who) {
  const std::string path = options.camera_file.empty() ? default_file : options.camera_file;
  config::CameraInfo info = config::load_camera_info(path);
  if (info.width != options.width || info.height != options.height) {
    throw InputError(who + ": camera file " + path + " is " + std::to_string(info.width) + "x" +
                     std::to_string(info.height) + " but the stream mode is " +
                     std::to_string(options.width) + "x" + std::to_string(options.height));
  }
  return info;
}

std::int64_t DeviceClock::to_ns(std::uint64_t ticks) {
  const std::uint64_t mask = wrap_bits_ >= 64 ? ~0ULL : ((1ULL << wrap_bits_) - 1);
  ticks &= mask;
  if (!started_) {
    started_ = true;
    last_ticks_ = ticks;
    unwrapped_ticks_ = 0;
    anchor_ns_ = std::chrono::duration_cast<std::chrono::nanoseconds>(
                     std::chrono::system_clock::now().time_since_epoch())
                     .count();
  } else {
    // Signed difference modulo 2^wrap_bits: a wrap and a slightly older stamp both come out
    // right as long as consecutive stamps are less than half the counter range apart.
    std::uint64_t diff = (ticks - last_ticks_) & mask;
    std::int64_t step = static_cast<std::int64_t>(diff);
    if (wrap_bits_ < 64 && diff >= (1ULL << (wrap_bits_ - 1))) {
      step -= static_cast<std::int64_t>(1ULL << wrap_bits_);
    }
    unwrapped_ticks_ += step;
    last_ticks_ = ticks;
  }
  return anchor_ns_ + unwrapped_ticks_ * ns_num_ / ns_den_;
}

}  // namespace detail

}  // namespace hq::sources
