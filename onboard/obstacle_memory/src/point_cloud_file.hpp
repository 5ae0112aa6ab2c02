#pragma once
/// The obstacle map as a file other tools read: PCD (PCL, CloudCompare, Foxglove) or PLY
/// (MeshLab, Blender, Open3D). Written here rather than with pcl::io, whose Debian build links
/// VTK and its renderer: the vehicle's programs carry no GUI library (tests/install/).

#include <Eigen/Core>

#include <span>
#include <string>

namespace hq::obstacle_memory {

/// Writes x y z (float32) per point as PCD v0.7: binary as pcl::io::savePCDFileBinary writes it,
/// or ASCII for an empty cloud (a valid file PCL's reader accepts; binary has no data to map).
/// @throws hq::InputError naming the path if it cannot be opened or written.
void write_pcd(const std::string& path, std::span<const Eigen::Vector3f> points);

/// Writes x y z (float32) per point as a binary little-endian PLY 1.0 vertex list.
/// @throws hq::InputError naming the path if it cannot be opened or written.
void write_ply(const std::string& path, std::span<const Eigen::Vector3f> points);

}  // namespace hq::obstacle_memory
