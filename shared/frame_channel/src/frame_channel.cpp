#include "hq/frame_channel/frame_channel.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"

#include <atomic>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <fcntl.h>
#include <new>
#include <signal.h>
#include <string>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

namespace hq::frame_channel {

namespace {

constexpr std::uint32_t kMagic = 0x43465148;  // "HQFC" little-endian
constexpr std::uint32_t kVersion = 1;
constexpr std::size_t kAlign = 64;
/// A channel whose writer has not beaten for this long may be taken over by a new writer.
constexpr std::int64_t kStaleWriterNs = 5'000'000'000;

static_assert(std::atomic<std::uint64_t>::is_always_lock_free);
static_assert(std::atomic<std::int64_t>::is_always_lock_free);
static_assert(std::atomic<std::uint32_t>::is_always_lock_free);

/// Written once by the writer before `magic` is released; read-only afterwards except for the
/// atomics at the end.
struct alignas(kAlign) Header {
  std::atomic<std::uint32_t>
      magic;  ///< Stored last (release): the rest is valid once it reads kMagic.
  std::uint32_t version;
  std::uint32_t slot_count;
  std::uint32_t header_bytes;
  std::uint64_t slot_stride;
  std::uint64_t image_offset;  ///< In a slot.
  std::uint64_t depth_offset;  ///< In a slot.
  std::uint64_t total_bytes;
  std::int32_t width, height, channels;
  std::int32_t writer_pid;
  double fx, fy, cx, cy;
  std::int64_t generation;  ///< Distinguishes two writers of one pid (CLOCK_MONOTONIC at start).
  alignas(kAlign) std::atomic<std::int64_t> heartbeat_ns;
  std::atomic<std::uint64_t> published;  ///< Frames published; the newest is published - 1.
  std::atomic<std::uint32_t> closed;
  std::atomic<std::int64_t> time_origin_ns;  ///< 0: not set.
};

/// The slot's metadata; the image and depth bytes follow at the header's offsets.
struct alignas(kAlign) SlotHeader {
  std::atomic<std::uint64_t> seq;  ///< Seqlock: odd while the writer fills the slot.
  std::uint64_t index;
  std::int64_t t_ns;
  std::uint32_t has_truth;
  SitlTruth truth;
};

constexpr std::size_t round_up(std::size_t n) { return (n + kAlign - 1) / kAlign * kAlign; }

struct Layout {
  std::size_t header_bytes, image_offset, depth_offset, slot_stride, total_bytes;
};

Layout layout_for(int width, int height, int channels) {
  Layout l{};
  const auto pixels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  l.header_bytes = round_up(sizeof(Header));
  l.image_offset = round_up(sizeof(SlotHeader));
  l.depth_offset = l.image_offset + round_up(pixels * static_cast<std::size_t>(channels));
  l.slot_stride = l.depth_offset + round_up(pixels * sizeof(float));
  l.total_bytes = l.header_bytes + kSlots * l.slot_stride;
  return l;
}

Header* header_of(const Mapping& m) { return static_cast<Header*>(m.base); }

unsigned char* slot_base(const Mapping& m, std::uint64_t index) {
  const Header* h = header_of(m);
  return static_cast<unsigned char*>(m.base) + h->header_bytes +
         (index % h->slot_count) * h->slot_stride;
}

std::string errno_text(const std::string& call, const std::string& name) {
  return call + "(" + name + "): " + std::strerror(errno);
}

void unmap(Mapping& m) {
  if (m.base != nullptr) munmap(m.base, m.bytes);
  m = Mapping{};
}

/// Maps an existing channel read-only; on failure returns a reason instead.
bool map_existing(const std::string& shm, Mapping& out, std::string& reason) {
  const int fd = shm_open(shm.c_str(), O_RDONLY, 0);
  if (fd < 0) {
    reason = errno == ENOENT ? "no such shared-memory object (is the writer, hq-sim --sitl, "
                               "running?)"
                             : errno_text("shm_open", shm);
    return false;
  }
  struct stat st {};
  if (fstat(fd, &st) != 0) {
    reason = errno_text("fstat", shm);
    close(fd);
    return false;
  }
  const auto bytes = static_cast<std::size_t>(st.st_size);
  if (bytes < sizeof(Header)) {
    reason = "size " + std::to_string(bytes) + " bytes, smaller than a frame-channel header";
    close(fd);
    return false;
  }
  void* base = mmap(nullptr, bytes, PROT_READ, MAP_SHARED, fd, 0);
  close(fd);  // the mapping keeps the object
  if (base == MAP_FAILED) {
    reason = errno_text("mmap", shm);
    return false;
  }
  out.base = base;
  out.bytes = bytes;
  const Header* h = header_of(out);
  const std::uint32_t magic = h->magic.load(std::memory_order_acquire);
  if (magic != kMagic) {
    reason =
        magic == 0 ? "not initialised yet (writer starting)" : "not a frame channel (bad magic)";
  } else if (h->version != kVersion) {
    reason = "version " + std::to_string(h->version) + ", expected " + std::to_string(kVersion);
  } else if (h->slot_count != kSlots || h->width <= 0 || h->height <= 0 ||
             (h->channels != 1 && h->channels != 3)) {
    reason = "bad geometry " + std::to_string(h->width) + "x" + std::to_string(h->height) + "x" +
             std::to_string(h->channels) + " with " + std::to_string(h->slot_count) + " slots";
  } else {
    const Layout l = layout_for(h->width, h->height, h->channels);
    if (l.total_bytes != h->total_bytes || l.total_bytes > bytes ||
        l.slot_stride != h->slot_stride || l.image_offset != h->image_offset ||
        l.depth_offset != h->depth_offset || l.header_bytes != h->header_bytes) {
      reason = "size " + std::to_string(bytes) + " bytes does not match its geometry " +
               std::to_string(h->width) + "x" + std::to_string(h->height) + "x" +
               std::to_string(h->channels) + " (" + std::to_string(l.total_bytes) + " bytes)";
    } else {
      return true;
    }
  }
  unmap(out);
  return false;
}

ChannelGeometry geometry_of(const Header& h) {
  ChannelGeometry g;
  g.width = h.width;
  g.height = h.height;
  g.channels = h.channels;
  g.fx = h.fx;
  g.fy = h.fy;
  g.cx = h.cx;
  g.cy = h.cy;
  return g;
}

bool pid_alive(int pid) { return pid > 0 && (kill(pid, 0) == 0 || errno == EPERM); }

/// Copies a (possibly non-continuous) matrix row by row into dst.
void copy_rows(const cv::Mat& src, unsigned char* dst) {
  const std::size_t row_bytes = static_cast<std::size_t>(src.cols) * src.elemSize();
  if (src.isContinuous()) {
    std::memcpy(dst, src.data, row_bytes * static_cast<std::size_t>(src.rows));
    return;
  }
  for (int r = 0; r < src.rows; ++r) {
    std::memcpy(dst + static_cast<std::size_t>(r) * row_bytes, src.ptr(r), row_bytes);
  }
}

}  // namespace

std::string shm_name(const std::string& name) {
  bool ok = !name.empty() && name.size() <= 200;
  for (const char c : name) {
    ok = ok && ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                c == '.' || c == '_' || c == '-');
  }
  if (!ok) {
    throw InputError("frame channel name \"" + name +
                     "\": expected 1..200 characters of [A-Za-z0-9._-]");
  }
  return "/hq-" + name;
}

// ---------------------------------------------------------------------------------------------
// Writer

FrameChannelWriter::FrameChannelWriter(const std::string& name, int width, int height, int channels)
    : FrameChannelWriter(name, ChannelGeometry{width, height, channels, 0.0, 0.0, 0.0, 0.0}) {}

FrameChannelWriter::FrameChannelWriter(const std::string& name, const ChannelGeometry& geometry)
    : name_(shm_name(name)), geometry_(geometry) {
  if (geometry.width <= 0 || geometry.height <= 0 || geometry.width > 8192 ||
      geometry.height > 8192 || (geometry.channels != 1 && geometry.channels != 3)) {
    throw InputError(name_ + ": geometry " + std::to_string(geometry.width) + "x" +
                     std::to_string(geometry.height) + "x" + std::to_string(geometry.channels) +
                     ", expected 1..8192 x 1..8192 with 1 (gray) or 3 (BGR) channels");
  }
  const Layout l = layout_for(geometry.width, geometry.height, geometry.channels);
  int fd = shm_open(name_.c_str(), O_RDWR | O_CREAT | O_EXCL, 0600);
  if (fd < 0 && errno == EEXIST) {
    // Another writer's, or one a crashed writer left behind: refuse the first, replace the
    // second.
    Mapping old;
    std::string reason;
    if (map_existing(name_, old, reason)) {
      const Header* h = header_of(old);
      const int pid = h->writer_pid;
      const bool closed = h->closed.load(std::memory_order_acquire) != 0;
      // A live pid with a silent heartbeat is a recycled pid, not a writer.
      const bool beating =
          monotonic_now_ns() - h->heartbeat_ns.load(std::memory_order_acquire) < kStaleWriterNs;
      unmap(old);
      if (!closed && beating && pid_alive(pid)) {
        throw InputError(name_ + ": frame channel in use by a live writer (pid " +
                         std::to_string(pid) + "); choose another --channel name");
      }
    }
    shm_unlink(name_.c_str());
    fd = shm_open(name_.c_str(), O_RDWR | O_CREAT | O_EXCL, 0600);
  }
  if (fd < 0) throw InputError(errno_text("shm_open", name_));
  if (ftruncate(fd, static_cast<off_t>(l.total_bytes)) != 0) {
    const std::string message = errno_text("ftruncate", name_);
    close(fd);
    shm_unlink(name_.c_str());
    throw InputError(message);
  }
  void* base = mmap(nullptr, l.total_bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  close(fd);
  if (base == MAP_FAILED) {
    const std::string message = errno_text("mmap", name_);
    shm_unlink(name_.c_str());
    throw InputError(message);
  }
  map_.base = base;
  map_.bytes = l.total_bytes;

  // The object is zero-filled by ftruncate; construct the atomics in place, fill the rest, and
  // release the magic last.
  auto* h = new (base) Header{};
  h->version = kVersion;
  h->slot_count = kSlots;
  h->header_bytes = static_cast<std::uint32_t>(l.header_bytes);
  h->slot_stride = l.slot_stride;
  h->image_offset = l.image_offset;
  h->depth_offset = l.depth_offset;
  h->total_bytes = l.total_bytes;
  h->width = geometry.width;
  h->height = geometry.height;
  h->channels = geometry.channels;
  h->writer_pid = static_cast<std::int32_t>(getpid());
  h->fx = geometry.fx;
  h->fy = geometry.fy;
  h->cx = geometry.cx;
  h->cy = geometry.cy;
  h->generation = monotonic_now_ns();
  h->heartbeat_ns.store(monotonic_now_ns(), std::memory_order_relaxed);
  h->published.store(0, std::memory_order_relaxed);
  h->closed.store(0, std::memory_order_relaxed);
  h->time_origin_ns.store(0, std::memory_order_relaxed);
  for (int i = 0; i < kSlots; ++i) {
    new (slot_base(map_, static_cast<std::uint64_t>(i))) SlotHeader{};
  }
  h->magic.store(kMagic, std::memory_order_release);
}

FrameChannelWriter::~FrameChannelWriter() {
  if (map_.base == nullptr) return;
  header_of(map_)->closed.store(1, std::memory_order_release);
  unmap(map_);
  shm_unlink(name_.c_str());
}

void FrameChannelWriter::set_time_origin(std::int64_t time_origin_ns) {
  header_of(map_)->time_origin_ns.store(time_origin_ns, std::memory_order_release);
}

void FrameChannelWriter::heartbeat() {
  header_of(map_)->heartbeat_ns.store(monotonic_now_ns(), std::memory_order_release);
}

bool FrameChannelWriter::publish(std::int64_t t_ns, const cv::Mat& image, const cv::Mat& depth_m,
                                 const SitlTruth* truth) {
  if (image.type() != CV_8UC(geometry_.channels) || image.cols != geometry_.width ||
      image.rows != geometry_.height || depth_m.type() != CV_32FC1 ||
      depth_m.cols != geometry_.width || depth_m.rows != geometry_.height) {
    return false;
  }
  Header* h = header_of(map_);
  const std::uint64_t index = published_;
  unsigned char* base = slot_base(map_, index);
  auto* slot = reinterpret_cast<SlotHeader*>(base);

  // Seqlock write side (Boehm 2012, "Can seqlocks get along with programming language memory
  // models?"): odd, release fence, data, even with release.
  const std::uint64_t seq = slot->seq.load(std::memory_order_relaxed);
  slot->seq.store(seq + 1, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  slot->index = index;
  slot->t_ns = t_ns;
  slot->has_truth = truth != nullptr ? 1u : 0u;
  slot->truth = truth != nullptr ? *truth : SitlTruth{};
  copy_rows(image, base + h->image_offset);
  copy_rows(depth_m, base + h->depth_offset);
  slot->seq.store(seq + 2, std::memory_order_release);

  published_ = index + 1;
  h->published.store(published_, std::memory_order_release);
  h->heartbeat_ns.store(monotonic_now_ns(), std::memory_order_release);
  return true;
}

// ---------------------------------------------------------------------------------------------
// Reader

FrameChannelReader::FrameChannelReader(const std::string& name, const ReaderOptions& options)
    : name_(shm_name(name)), options_(options) {
  std::string reason;
  if (!map_existing(name_, map_, reason)) {
    throw InputError("frame channel " + name_ + ": " + reason);
  }
  geometry_ = geometry_of(*header_of(map_));
  if ((options_.expect_width > 0 && geometry_.width != options_.expect_width) ||
      (options_.expect_height > 0 && geometry_.height != options_.expect_height)) {
    const std::string found =
        std::to_string(geometry_.width) + "x" + std::to_string(geometry_.height);
    unmap(map_);
    throw InputError("frame channel " + name_ + ": frames are " + found + ", expected " +
                     std::to_string(options_.expect_width) + "x" +
                     std::to_string(options_.expect_height));
  }
  check_writer(monotonic_now_ns());
}

FrameChannelReader::~FrameChannelReader() { unmap(map_); }

int FrameChannelReader::writer_pid() const { return header_of(map_)->writer_pid; }

std::int64_t FrameChannelReader::time_origin_ns() const {
  return header_of(map_)->time_origin_ns.load(std::memory_order_acquire);
}

void FrameChannelReader::check_writer(std::int64_t now_ns) {
  const Header* h = header_of(map_);
  const bool closed = h->closed.load(std::memory_order_acquire) != 0;
  const std::int64_t beat_ns = h->heartbeat_ns.load(std::memory_order_acquire);
  writer_alive_ = !closed && now_ns - beat_ns <= options_.dead_after_ns;
}

bool FrameChannelReader::try_reopen() {
  Mapping fresh;
  std::string reason;
  if (!map_existing(name_, fresh, reason)) return false;
  const Header* old_h = header_of(map_);
  const Header* new_h = header_of(fresh);
  const ChannelGeometry g = geometry_of(*new_h);
  const bool same_writer =
      new_h->writer_pid == old_h->writer_pid && new_h->generation == old_h->generation;
  if (same_writer || g.width != geometry_.width || g.height != geometry_.height ||
      g.channels != geometry_.channels) {
    unmap(fresh);
    return false;
  }
  unmap(map_);
  map_ = fresh;
  geometry_ = g;  // same size; the intrinsics may differ
  have_taken_ = false;
  ++restarts_;
  return true;
}

bool FrameChannelReader::take_latest(cv::Mat& image, cv::Mat& depth_m, FrameInfo& info) {
  const std::int64_t now_ns = monotonic_now_ns();
  check_writer(now_ns);
  if (!writer_alive_ && now_ns - last_reopen_ns_ >= options_.reopen_interval_ns) {
    last_reopen_ns_ = now_ns;
    if (try_reopen()) check_writer(now_ns);
  }
  // Frames a gone writer published before it went can still be taken.
  image.create(geometry_.height, geometry_.width, CV_8UC(geometry_.channels));
  depth_m.create(geometry_.height, geometry_.width, CV_32FC1);
  const Header* h = header_of(map_);
  const std::size_t image_bytes = static_cast<std::size_t>(geometry_.width) *
                                  static_cast<std::size_t>(geometry_.height) *
                                  static_cast<std::size_t>(geometry_.channels);
  const std::size_t depth_bytes = static_cast<std::size_t>(geometry_.width) *
                                  static_cast<std::size_t>(geometry_.height) * sizeof(float);
  // A reader overtaken kSlots frames during one copy retries with the newest; 64 attempts is
  // far beyond what a 30 Hz writer can cause.
  for (int attempt = 0; attempt < 64; ++attempt) {
    const std::uint64_t published = h->published.load(std::memory_order_acquire);
    if (published == 0) return false;
    const std::uint64_t index = published - 1;
    if (have_taken_ && index <= last_index_) return false;
    const unsigned char* base = slot_base(map_, index);
    const auto* slot = reinterpret_cast<const SlotHeader*>(base);
    const std::uint64_t seq_before = slot->seq.load(std::memory_order_acquire);
    if ((seq_before & 1u) != 0) {
      ++retries_;
      continue;
    }
    const std::uint64_t slot_index = slot->index;
    FrameInfo copied;
    copied.index = slot_index;
    copied.t_ns = slot->t_ns;
    copied.has_truth = slot->has_truth != 0;
    copied.truth = slot->truth;
    std::memcpy(image.data, base + h->image_offset, image_bytes);
    std::memcpy(depth_m.data, base + h->depth_offset, depth_bytes);
    std::atomic_thread_fence(std::memory_order_acquire);
    const std::uint64_t seq_after = slot->seq.load(std::memory_order_relaxed);
    if (seq_after != seq_before || slot_index != index) {
      ++retries_;
      continue;
    }
    if (have_taken_) missed_ += index - last_index_ - 1;
    have_taken_ = true;
    last_index_ = index;
    ++taken_;
    info = copied;
    return true;
  }
  return false;
}

}  // namespace hq::frame_channel
