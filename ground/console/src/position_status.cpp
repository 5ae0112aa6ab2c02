#include "hq/console/position_status.hpp"

#include "hq/base/format_into.hpp"

#include <cstdio>

namespace hq::console {

bool position_lost(std::uint8_t position_invalid_reason) {
  return position_invalid_reason >= 2 && position_invalid_reason <= 4;
}

const char* position_invalid_text(std::uint8_t reason, float age_s, float sigma_m, char* out,
                                  std::size_t size) {
  if (size == 0) return out;
  switch (reason) {
    case 0:
      out[0] = '\0';
      break;
    case 1:
      hq::format_into(out, size, "no marker seen yet");
      break;
    case 2:
      hq::format_into(out, size, "no marker for {:.1f} s", static_cast<double>(age_s));
      break;
    case 3:
      hq::format_into(out, size, "position uncertainty {:.2f} m, over its bound",
                      static_cast<double>(sigma_m));
      break;
    case 4:
      hq::format_into(out, size, "markers or velocity disagree with the estimate");
      break;
    default:
      hq::format_into(out, size, "unknown reason {}", static_cast<unsigned>(reason));
      break;
  }
  return out;
}

}  // namespace hq::console
