#pragma once

// Shared by the client and server links: decoding the PLC's inputs from register words,
// and libmodbus context ownership.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <modbus/modbus.h>

#include "mosaicloc/io/plc_link.hpp"
#include "mosaicloc/io/registers.hpp"

namespace mosaicloc::io::detail {

struct ModbusDeleter {
  void operator()(modbus_t* context) const {
    modbus_close(context);
    modbus_free(context);
  }
};
using ModbusContext = std::unique_ptr<modbus_t, ModbusDeleter>;

/// A new libmodbus context for the options' transport (not yet connected); throws
/// core::Error when libmodbus refuses the settings.
ModbusContext NewContext(const PlcLinkOptions& options, bool server);

/// Lowest register and count covering a set of fields.
struct RegisterRange {
  int base = 0;
  int count = 0;
};
RegisterRange RangeOf(const std::vector<const RegisterField*>& fields);

/// Turns input register words into PlcInputs. Keeps the counters' unwrap state, so 16-bit
/// counters and scaled counters stay continuous.
class InputDecoder {
 public:
  explicit InputDecoder(const RegisterMap& map);
  /// `words` holds the registers from `base`.
  PlcInputs Decode(const std::uint16_t* words, int base);

 private:
  static std::int32_t Ticks(const RegisterField& field, CounterUnwrapper* unwrapper, std::int64_t count);
  RegisterMap map_;
  std::vector<CounterUnwrapper> unwrappers_;  ///< one per counter of the kind (the steering angle's unused)
};

}  // namespace mosaicloc::io::detail
