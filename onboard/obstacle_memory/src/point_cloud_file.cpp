#include "point_cloud_file.hpp"

#include "hq/base/error.hpp"

#include <bit>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <vector>

namespace hq::obstacle_memory {
namespace {

constexpr std::size_t kBytesPerPoint = 3 * sizeof(float);

std::ofstream open_for_writing(const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) {
    throw InputError("memory map " + path + ": cannot open for writing: " + std::strerror(errno));
  }
  return out;
}

void finish(std::ofstream& out, const std::string& path, std::size_t point_count) {
  out.close();
  if (!out) {
    throw InputError("memory map " + path + ": writing " + std::to_string(point_count) +
                     " points failed: " + std::strerror(errno));
  }
}

/// x y z as float32 little endian, whatever the host's byte order (PLY says little endian;
/// PCL reads binary PCD in the host's order, which is little endian on every target we ship).
std::vector<char> little_endian_xyz(std::span<const Eigen::Vector3f> points) {
  std::vector<char> bytes(points.size() * kBytesPerPoint);
  std::size_t at = 0;
  for (const Eigen::Vector3f& p : points) {
    for (int axis = 0; axis < 3; ++axis) {
      const auto bits = std::bit_cast<std::uint32_t>(p[axis]);
      for (int byte = 0; byte < 4; ++byte) {
        bytes[at++] = static_cast<char>((bits >> (8 * byte)) & 0xFFU);
      }
    }
  }
  return bytes;
}

}  // namespace

void write_pcd(const std::string& path, std::span<const Eigen::Vector3f> points) {
  std::ofstream out = open_for_writing(path);
  const std::string count = std::to_string(points.size());
  out << "# .PCD v0.7 - Point Cloud Data file format\n"
      << "VERSION 0.7\n"
      << "FIELDS x y z\n"
      << "SIZE 4 4 4\n"
      << "TYPE F F F\n"
      << "COUNT 1 1 1\n"
      << "WIDTH " << count << "\n"
      << "HEIGHT 1\n"
      << "VIEWPOINT 0 0 0 1 0 0 0\n"
      << "POINTS " << count << "\n"
      << "DATA " << (points.empty() ? "ascii" : "binary") << "\n";
  const std::vector<char> bytes = little_endian_xyz(points);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  finish(out, path, points.size());
}

void write_ply(const std::string& path, std::span<const Eigen::Vector3f> points) {
  std::ofstream out = open_for_writing(path);
  out << "ply\n"
      << "format binary_little_endian 1.0\n"
      << "comment HaptiQuad obstacle memory\n"
      << "element vertex " << points.size() << "\n"
      << "property float x\n"
      << "property float y\n"
      << "property float z\n"
      << "end_header\n";
  const std::vector<char> bytes = little_endian_xyz(points);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  finish(out, path, points.size());
}

}  // namespace hq::obstacle_memory
