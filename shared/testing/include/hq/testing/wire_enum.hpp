#pragma once
// What a broken or hostile sender puts on the wire: any integer in an IDL enum field, as the
// deserializer copies its bytes. A static_cast to the enum of a value outside its range has an
// unspecified result (-Wconversion says so), so tests of the validators write the bytes instead.
#include <cstdint>
#include <cstring>

namespace hq::testing {

template <typename Enum>
Enum wire_enum(std::int32_t value) {
  static_assert(sizeof(Enum) == sizeof(value), "IDL enums travel as 32-bit integers");
  Enum field;
  std::memcpy(&field, &value, sizeof(field));
  return field;
}

}  // namespace hq::testing
