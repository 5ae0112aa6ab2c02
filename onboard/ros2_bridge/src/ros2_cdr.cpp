#include "hq/ros2_bridge/ros2_cdr.hpp"

#include <bit>
#include <cstring>

namespace hq::ros2_bridge {

static_assert(std::endian::native == std::endian::little,
              "CdrWriter copies values in host order and writes CDR_LE");

namespace {

constexpr std::size_t kHeaderBytes = 4;  // the encapsulation header; alignment starts after it

void time(const builtin_interfaces_msg_dds__Time_& t, CdrWriter& out) {
  out.i32(t.sec);
  out.u32(t.nanosec);
}

void header(const std_msgs_msg_dds__Header_& h, CdrWriter& out) {
  time(h.stamp, out);
  out.string(h.frame_id);
}

void vector3(const geometry_msgs_msg_dds__Vector3_& v, CdrWriter& out) {
  out.f64(v.x);
  out.f64(v.y);
  out.f64(v.z);
}

void quaternion(const geometry_msgs_msg_dds__Quaternion_& q, CdrWriter& out) {
  out.f64(q.x);
  out.f64(q.y);
  out.f64(q.z);
  out.f64(q.w);
}

void transform_stamped(const TransformStamped& t, CdrWriter& out) {
  header(t.header, out);
  out.string(t.child_frame_id);
  vector3(t.transform.translation, out);
  quaternion(t.transform.rotation, out);
}

}  // namespace

void CdrWriter::begin() {
  size_ = 0;
  overflowed_ = false;
  if (buffer_.size() < kHeaderBytes) {
    overflowed_ = true;
    return;
  }
  const std::uint8_t cdr_le[kHeaderBytes] = {0x00, 0x01, 0x00, 0x00};
  std::memcpy(buffer_.data(), cdr_le, kHeaderBytes);
  size_ = kHeaderBytes;
}

void CdrWriter::align(std::size_t n) {
  const std::size_t body = size_ - kHeaderBytes;
  const std::size_t padding = (n - body % n) % n;
  if (size_ + padding > buffer_.size()) {
    overflowed_ = true;
    return;
  }
  std::memset(buffer_.data() + size_, 0, padding);
  size_ += padding;
}

void CdrWriter::put(const void* value, std::size_t n, std::size_t alignment) {
  align(alignment);
  if (overflowed_ || size_ + n > buffer_.size()) {
    overflowed_ = true;
    return;
  }
  std::memcpy(buffer_.data() + size_, value, n);
  size_ += n;
}

void CdrWriter::string(const char* text) {
  const std::size_t n = text != nullptr ? std::strlen(text) : 0;
  u32(static_cast<std::uint32_t>(n + 1));  // the length counts the terminating NUL
  if (overflowed_ || size_ + n + 1 > buffer_.size()) {
    overflowed_ = true;
    return;
  }
  if (n > 0) std::memcpy(buffer_.data() + size_, text, n);
  buffer_[size_ + n] = 0;
  size_ += n + 1;
}

void CdrWriter::bytes(const std::uint8_t* data, std::uint32_t n) {
  u32(n);
  if (overflowed_ || size_ + n > buffer_.size()) {
    overflowed_ = true;
    return;
  }
  if (n > 0) std::memcpy(buffer_.data() + size_, data, n);
  size_ += n;
}

void CdrWriter::f64_array(const double* values, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) f64(values[i]);
}

bool serialize(const Odometry& m, CdrWriter& out) {
  out.begin();
  header(m.header, out);
  out.string(m.child_frame_id);
  out.f64(m.pose.pose.position.x);
  out.f64(m.pose.pose.position.y);
  out.f64(m.pose.pose.position.z);
  quaternion(m.pose.pose.orientation, out);
  out.f64_array(m.pose.covariance, 36);
  vector3(m.twist.twist.linear, out);
  vector3(m.twist.twist.angular, out);
  out.f64_array(m.twist.covariance, 36);
  return !out.overflowed();
}

bool serialize(const Imu& m, CdrWriter& out) {
  out.begin();
  header(m.header, out);
  quaternion(m.orientation, out);
  out.f64_array(m.orientation_covariance, 9);
  vector3(m.angular_velocity, out);
  out.f64_array(m.angular_velocity_covariance, 9);
  vector3(m.linear_acceleration, out);
  out.f64_array(m.linear_acceleration_covariance, 9);
  return !out.overflowed();
}

bool serialize(const TfMessage& m, CdrWriter& out) {
  out.begin();
  out.u32(m.transforms._length);
  for (std::uint32_t i = 0; i < m.transforms._length; ++i) {
    transform_stamped(m.transforms._buffer[i], out);
  }
  return !out.overflowed();
}

bool serialize(const PointCloud2& m, CdrWriter& out) {
  out.begin();
  header(m.header, out);
  out.u32(m.height);
  out.u32(m.width);
  out.u32(m.fields._length);
  for (std::uint32_t i = 0; i < m.fields._length; ++i) {
    const PointField& f = m.fields._buffer[i];
    out.string(f.name);
    out.u32(f.offset);
    out.u8(f.datatype);
    out.u32(f.count);
  }
  out.boolean(m.is_bigendian);
  out.u32(m.point_step);
  out.u32(m.row_step);
  out.bytes(m.data._buffer, m.data._length);
  out.boolean(m.is_dense);
  return !out.overflowed();
}

bool serialize(const CompressedImage& m, CdrWriter& out) {
  out.begin();
  header(m.header, out);
  out.string(m.format);
  out.bytes(m.data._buffer, m.data._length);
  return !out.overflowed();
}

bool serialize(const CameraInfo& m, CdrWriter& out) {
  out.begin();
  header(m.header, out);
  out.u32(m.height);
  out.u32(m.width);
  out.string(m.distortion_model);
  out.u32(m.d._length);
  out.f64_array(m.d._buffer, m.d._length);
  out.f64_array(m.k, 9);
  out.f64_array(m.r, 9);
  out.f64_array(m.p, 12);
  out.u32(m.binning_x);
  out.u32(m.binning_y);
  out.u32(m.roi.x_offset);
  out.u32(m.roi.y_offset);
  out.u32(m.roi.height);
  out.u32(m.roi.width);
  out.boolean(m.roi.do_rectify);
  return !out.overflowed();
}

bool serialize(const RosClockMsg& m, CdrWriter& out) {
  out.begin();
  time(m.clock, out);
  return !out.overflowed();
}

// The .msg texts of the ROS 2 message definitions (fields in order, as the IDL has them), with
// their dependencies after rosbag2's separator. Types are written package-qualified throughout.
#define HQ_MSG(type)                                                                               \
  "\n================================================================================\nMSG: " type \
  "\n"
#define HQ_TIME HQ_MSG("builtin_interfaces/Time") "int32 sec\nuint32 nanosec\n"
#define HQ_HEADER \
  HQ_MSG("std_msgs/Header") "builtin_interfaces/Time stamp\nstring frame_id\n" HQ_TIME
#define HQ_VECTOR3 HQ_MSG("geometry_msgs/Vector3") "float64 x\nfloat64 y\nfloat64 z\n"
#define HQ_POINT HQ_MSG("geometry_msgs/Point") "float64 x\nfloat64 y\nfloat64 z\n"
#define HQ_QUATERNION \
  HQ_MSG("geometry_msgs/Quaternion") "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
#define HQ_TRANSFORM_STAMPED               \
  HQ_MSG("geometry_msgs/TransformStamped") \
  "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n"    \
      HQ_HEADER HQ_MSG("geometry_msgs/Transform")                                         \
  "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n" HQ_VECTOR3 HQ_QUATERNION

template <>
const MessageDefinition& message_definition<Odometry>() {
  static const MessageDefinition kDefinition{
      "nav_msgs/msg/Odometry",
      "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
      "geometry_msgs/TwistWithCovariance twist\n" HQ_HEADER HQ_MSG(
          "geometry_msgs/PoseWithCovariance") "geometry_msgs/Pose pose\nfloat64[36] covariance\n"
          HQ_MSG("geometry_msgs/Pose") "geometry_msgs/Point position\n"
                                       "geometry_msgs/Quaternion orientation\n" HQ_POINT
              HQ_QUATERNION HQ_MSG("geometry_msgs/TwistWithCovariance")
                  "geometry_msgs/Twist twist\nfloat64[36] covariance\n" HQ_MSG("geometry_msgs/Twist")
                      "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n" HQ_VECTOR3};
  return kDefinition;
}

template <>
const MessageDefinition& message_definition<Imu>() {
  static const MessageDefinition kDefinition{
      "sensor_msgs/msg/Imu",
      "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n"
      "float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n"
      "float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n"
      "float64[9] linear_acceleration_covariance\n" HQ_HEADER HQ_QUATERNION HQ_VECTOR3};
  return kDefinition;
}

template <>
const MessageDefinition& message_definition<TfMessage>() {
  static const MessageDefinition kDefinition{
      "tf2_msgs/msg/TFMessage",
      "geometry_msgs/TransformStamped[] transforms\n" HQ_TRANSFORM_STAMPED};
  return kDefinition;
}

template <>
const MessageDefinition& message_definition<PointCloud2>() {
  static const MessageDefinition kDefinition{
      "sensor_msgs/msg/PointCloud2",
      "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\n"
      "bool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n" HQ_HEADER
          HQ_MSG("sensor_msgs/PointField") "uint8 INT8 = 1\nuint8 UINT8 = 2\nuint8 INT16 = 3\n"
                                           "uint8 UINT16 = 4\nuint8 INT32 = 5\nuint8 UINT32 = 6\n"
                                           "uint8 FLOAT32 = 7\nuint8 FLOAT64 = 8\n"
                                           "string name\nuint32 offset\nuint8 datatype\n"
                                           "uint32 count\n"};
  return kDefinition;
}

template <>
const MessageDefinition& message_definition<CompressedImage>() {
  static const MessageDefinition kDefinition{
      "sensor_msgs/msg/CompressedImage",
      "std_msgs/Header header\nstring format\nuint8[] data\n" HQ_HEADER};
  return kDefinition;
}

template <>
const MessageDefinition& message_definition<CameraInfo>() {
  static const MessageDefinition kDefinition{
      "sensor_msgs/msg/CameraInfo",
      "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
      "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n"
      "uint32 binning_y\nsensor_msgs/RegionOfInterest roi\n" HQ_HEADER
          HQ_MSG("sensor_msgs/RegionOfInterest") "uint32 x_offset\nuint32 y_offset\n"
                                                 "uint32 height\nuint32 width\nbool do_rectify\n"};
  return kDefinition;
}

template <>
const MessageDefinition& message_definition<RosClockMsg>() {
  static const MessageDefinition kDefinition{"rosgraph_msgs/msg/Clock",
                                             "builtin_interfaces/Time clock\n" HQ_TIME};
  return kDefinition;
}

#undef HQ_TRANSFORM_STAMPED
#undef HQ_QUATERNION
#undef HQ_POINT
#undef HQ_VECTOR3
#undef HQ_HEADER
#undef HQ_TIME
#undef HQ_MSG

}  // namespace hq::ros2_bridge
