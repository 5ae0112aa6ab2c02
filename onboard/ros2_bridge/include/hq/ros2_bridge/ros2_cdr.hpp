#pragma once
/// The ROS 2 messages (ros2_messages.hpp) as the bytes rmw_cyclonedds puts on the wire and a
/// ROS 2 bag stores (MCAP message encoding "cdr"): little-endian plain CDR (XCDR1), the 4-byte
/// encapsulation header 00 01 00 00 (CDR_LE, no options) first, each primitive aligned to its
/// size counted from after the header; strings as uint32 length (with the NUL) + bytes + NUL;
/// sequences as uint32 count + elements; fixed arrays as their elements alone.
///
/// Written here rather than taken from Cyclone's serializer: Cyclone serializes through a
/// sertype that only a DDS topic provides, into a serdata it allocates per sample, while the
/// flight record serializes on its log thread into one buffer sized once, with no DDS entity.
/// The unit tests compare these bytes with what Cyclone puts on the wire for the same message.
/// The message definitions for the schemas (ros2msg) are here too, one per type.

#include "hq/ros2_bridge/ros2_messages.hpp"

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace hq::ros2_bridge {

/// Serializes into a buffer sized once: nothing allocates after construction. A message that
/// would not fit sets overflowed() (its bytes are then incomplete and must not be written).
class CdrWriter {
 public:
  explicit CdrWriter(std::size_t capacity_bytes) : buffer_(capacity_bytes) {}
  /// Starts a message: the encapsulation header.
  void begin();
  void u8(std::uint8_t v) { put(&v, 1, 1); }
  void boolean(bool v) { u8(v ? 1 : 0); }
  void i32(std::int32_t v) { put(&v, 4, 4); }
  void u32(std::uint32_t v) { put(&v, 4, 4); }
  void f64(double v) { put(&v, 8, 8); }
  void string(const char* text);
  void bytes(const std::uint8_t* data, std::uint32_t n);  ///< uint8[]: count, then the bytes
  void f64_array(const double* values, std::size_t n);    ///< float64[N]: the values alone

  [[nodiscard]] bool overflowed() const { return overflowed_; }
  [[nodiscard]] std::span<const std::uint8_t> data() const { return {buffer_.data(), size_}; }
  [[nodiscard]] std::size_t capacity() const { return buffer_.size(); }

 private:
  void align(std::size_t n);
  // Host order is little-endian on every target (checked in ros2_cdr.cpp).
  void put(const void* value, std::size_t n, std::size_t alignment);

  std::vector<std::uint8_t> buffer_;
  std::size_t size_ = 0;
  bool overflowed_ = false;
};

/// Each message as one CDR message (begin() included); false when it did not fit.
bool serialize(const Odometry& m, CdrWriter& out);
bool serialize(const Imu& m, CdrWriter& out);
bool serialize(const TfMessage& m, CdrWriter& out);
bool serialize(const PointCloud2& m, CdrWriter& out);
bool serialize(const CompressedImage& m, CdrWriter& out);
bool serialize(const CameraInfo& m, CdrWriter& out);
bool serialize(const RosClockMsg& m, CdrWriter& out);

/// A type's ROS 2 name and its ros2msg schema (MCAP schema encoding "ros2msg"): the .msg text,
/// then each type it uses after a line of 80 '=' and "MSG: pkg/Type", as rosbag2 writes them.
struct MessageDefinition {
  const char* name;  ///< e.g. "nav_msgs/msg/Odometry"
  const char* text;
};
template <typename T>
const MessageDefinition& message_definition();
template <>
const MessageDefinition& message_definition<Odometry>();
template <>
const MessageDefinition& message_definition<Imu>();
template <>
const MessageDefinition& message_definition<TfMessage>();
template <>
const MessageDefinition& message_definition<PointCloud2>();
template <>
const MessageDefinition& message_definition<CompressedImage>();
template <>
const MessageDefinition& message_definition<CameraInfo>();
template <>
const MessageDefinition& message_definition<RosClockMsg>();

}  // namespace hq::ros2_bridge
