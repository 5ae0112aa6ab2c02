#include "hq/recording/tum_sequence.hpp"

#include "hq/base/error.hpp"

#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <filesystem>
#include <system_error>

namespace hq::recording {
namespace {

std::string describe_type(const cv::Mat& image) {
  const int depth = image.depth();
  const char* bits = depth == CV_8U    ? "8-bit unsigned"
                     : depth == CV_8S  ? "8-bit signed"
                     : depth == CV_16U ? "16-bit unsigned"
                     : depth == CV_16S ? "16-bit signed"
                     : depth == CV_32S ? "32-bit integer"
                     : depth == CV_32F ? "32-bit float"
                                       : "64-bit float";
  return std::string(bits) + " " + std::to_string(image.channels()) + "-channel";
}

std::string describe_size(const cv::Size& size) {
  return std::to_string(size.width) + "x" + std::to_string(size.height);
}

// Decodes one PNG; imread returns an empty Mat for any failure, so the reason is narrowed here.
cv::Mat read_png(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError(path + ": image file not found");
  }
  cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (image.empty()) {
    throw InputError(path + ": cannot decode image (unreadable, corrupt or not a PNG)");
  }
  return image;
}

struct DecodedFrame {
  cv::Mat bgr;
  cv::Mat depth_u16;
};

// Reads and checks one frame. expected_size is empty for frame 0, which defines it.
DecodedFrame read_frame(const RgbdFrameFiles& files, const cv::Size& expected_size) {
  DecodedFrame frame{read_png(files.rgb_path), read_png(files.depth_path)};
  if (frame.bgr.type() != CV_8UC3) {
    throw InputError(files.rgb_path + ": colour image is " + describe_type(frame.bgr) +
                     ", expected 8-bit 3-channel (CV_8UC3)");
  }
  if (frame.depth_u16.type() != CV_16UC1) {
    throw InputError(files.depth_path + ": depth image is " + describe_type(frame.depth_u16) +
                     ", expected 16-bit single-channel (CV_16UC1, TUM: 5000 units per metre)");
  }
  if (frame.depth_u16.size() != frame.bgr.size()) {
    throw InputError(files.depth_path + ": depth image is " +
                     describe_size(frame.depth_u16.size()) + ", colour image " + files.rgb_path +
                     " is " + describe_size(frame.bgr.size()) +
                     "; expected equal sizes (depth registered to colour)");
  }
  if (!expected_size.empty() && frame.bgr.size() != expected_size) {
    throw InputError(files.rgb_path + ": image is " + describe_size(frame.bgr.size()) +
                     ", expected " + describe_size(expected_size) + " like frame 0");
  }
  return frame;
}

}  // namespace

TumSequence::TumSequence(const std::string& dir, double max_dt_s) : directory_(dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw InputError(dir + ": TUM sequence directory not found");
  }
  const std::filesystem::path root(dir);
  const std::string rgb_list = (root / "rgb.txt").string();
  const std::string depth_list = (root / "depth.txt").string();
  // Read in sequence so that, of two bad lists, the error names rgb.txt.
  const std::vector<TumListEntry> rgb = read_tum_list(rgb_list);
  const std::vector<TumListEntry> depth = read_tum_list(depth_list);
  frames_ = associate_rgbd(rgb, depth, dir, max_dt_s);
  if (frames_.empty()) {
    throw InputError(rgb_list + ", " + depth_list + ": no colour/depth pair within " +
                     std::to_string(max_dt_s) + " s, expected at least one");
  }
  const std::filesystem::path ground_truth = root / "groundtruth.txt";
  if (std::filesystem::exists(ground_truth, ec)) {
    ground_truth_ = read_tum_trajectory(ground_truth.string());
  }
  const std::filesystem::path accelerometer = root / "accelerometer.txt";
  if (std::filesystem::exists(accelerometer, ec)) {
    accelerometer_ = read_tum_accelerometer(accelerometer.string());
  }
  image_size_ = read_frame(frames_.front(), cv::Size()).bgr.size();
}

const std::string& TumSequence::directory() const { return directory_; }
std::size_t TumSequence::size() const { return frames_.size(); }
const RgbdFrameFiles& TumSequence::frame(std::size_t i) const { return frames_.at(i); }
bool TumSequence::has_ground_truth() const { return !ground_truth_.empty(); }
const std::vector<StampedPose>& TumSequence::ground_truth() const { return ground_truth_; }
bool TumSequence::has_accelerometer() const { return !accelerometer_.empty(); }
const std::vector<AccelSample>& TumSequence::accelerometer() const { return accelerometer_; }
cv::Size TumSequence::image_size() const { return image_size_; }

void TumSequence::load(std::size_t i, cv::Mat& bgr, cv::Mat& depth_u16) const {
  const DecodedFrame frame = read_frame(frames_.at(i), image_size_);
  // Copy rather than rebind: the caller's buffers keep their addresses from frame to frame.
  frame.bgr.copyTo(bgr);
  frame.depth_u16.copyTo(depth_u16);
}

void depth_to_metres(const cv::Mat& depth_u16, double units_per_m, cv::Mat& depth_m) {
  if (depth_u16.type() != CV_16UC1) {
    throw InputError("depth_to_metres: depth image is " + describe_type(depth_u16) +
                     ", expected 16-bit single-channel (CV_16UC1)");
  }
  if (!std::isfinite(units_per_m) || !(units_per_m > 0.0)) {
    throw InputError("depth_to_metres: units_per_m = " + std::to_string(units_per_m) +
                     ", expected finite and > 0");
  }
  // A linear scale maps 0 (no data) to 0, so invalid pixels stay marked.
  depth_u16.convertTo(depth_m, CV_32FC1, 1.0 / units_per_m);
}

}  // namespace hq::recording
