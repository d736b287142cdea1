#include "mosaicloc/io/registers.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace mosaicloc::io {

const char* ToString(WordOrder order) { return order == WordOrder::kHighFirst ? "high_first" : "low_first"; }

std::int64_t RegisterField::MinCount() const {
  if (!is_signed) return 0;
  return width_bits == 32 ? -(std::int64_t{1} << 31) : -(std::int64_t{1} << 15);
}

std::int64_t RegisterField::MaxCount() const {
  const int bits = width_bits == 32 ? 32 : 16;
  return is_signed ? (std::int64_t{1} << (bits - 1)) - 1 : (std::int64_t{1} << bits) - 1;
}

std::string RegisterField::Describe() const {
  if (words() == 1) return fmt::format("{} (register {})", name, address);
  return fmt::format("{} (registers {}-{})", name, address, address + words() - 1);
}

std::vector<const RegisterField*> RegisterMap::Counters() const {
  if (kind == core::DriveKind::kTricycle) return {&drive_ticks, &steering_ticks};
  if (kind == core::DriveKind::kMecanum) return {&front_left_ticks, &front_right_ticks, &rear_left_ticks, &rear_right_ticks};
  return {&left_ticks, &right_ticks};
}

std::vector<std::int32_t> RegisterMap::CounterValues(const core::EncoderCounts& counts) const {
  return core::CountersOf(kind, counts);
}

std::vector<const RegisterField*> RegisterMap::Inputs() const {
  std::vector<const RegisterField*> inputs = Counters();
  inputs.insert(inputs.end(), {&plc_heartbeat, &fix_request, &relocalize_request});
  return inputs;
}

std::vector<const RegisterField*> RegisterMap::Outputs() const {
  return {&fix_x, &fix_y, &fix_yaw, &fix_status, &fix_quality, &fix_request_echo, &heartbeat, &fix_mode};
}

bool RegisterMap::Check(std::string* why) const {
  auto fail = [why](std::string message) {
    if (why != nullptr) *why = std::move(message);
    return false;
  };
  std::vector<const RegisterField*> all = Inputs();
  const std::vector<const RegisterField*> outputs = Outputs();
  all.insert(all.end(), outputs.begin(), outputs.end());
  for (const RegisterField* field : all) {
    if (field->width_bits != 16 && field->width_bits != 32) {
      return fail(fmt::format("{}: width_bits must be 16 or 32, not {}", field->name, field->width_bits));
    }
    if (field->address < 0 || field->address + field->words() - 1 > 65535) {
      return fail(fmt::format("{}: address {} is outside the holding registers 0-65535", field->name, field->address));
    }
    if (!(field->scale > 0.0) || !std::isfinite(field->scale)) {
      return fail(fmt::format("{}: scale must be a positive number", field->name));
    }
  }
  // Counters, heartbeats, status and quality are plain integers.
  for (const RegisterField* field :
       {&plc_heartbeat, &fix_request, &relocalize_request, &fix_status, &fix_quality, &fix_request_echo, &heartbeat,
        &fix_mode}) {
    if (field->scale != 1.0) return fail(fmt::format("{}: scale must be 1 (it is a plain integer)", field->name));
  }
  if (fix_quality.MaxCount() < 1000) return fail("fix_quality: must hold 0-1000 (unsigned, or 32 bits)");
  for (std::size_t i = 0; i < all.size(); ++i) {
    for (std::size_t j = i + 1; j < all.size(); ++j) {
      const RegisterField& a = *all[i];
      const RegisterField& b = *all[j];
      if (a.address < b.address + b.words() && b.address < a.address + a.words()) {
        return fail(fmt::format("{} overlaps {}", a.Describe(), b.Describe()));
      }
    }
  }
  return true;
}

std::string RegisterSpan::Describe() const {
  std::string names;
  for (const RegisterField* field : fields) names += (names.empty() ? "" : ", ") + field->name;
  if (count == 1) return fmt::format("holding register {} ({})", address, names);
  return fmt::format("holding registers {}-{} ({})", address, address + count - 1, names);
}

std::vector<RegisterSpan> GroupIntoSpans(std::vector<const RegisterField*> fields, int max_gap, int max_count) {
  std::sort(fields.begin(), fields.end(),
            [](const RegisterField* a, const RegisterField* b) { return a->address < b->address; });
  std::vector<RegisterSpan> spans;
  for (const RegisterField* field : fields) {
    const int end = field->address + field->words();
    if (!spans.empty()) {
      RegisterSpan& last = spans.back();
      const int last_end = last.address + last.count;
      if (field->address - last_end <= max_gap && end - last.address <= max_count) {
        last.count = std::max(last_end, end) - last.address;
        last.fields.push_back(field);
        continue;
      }
    }
    spans.push_back(RegisterSpan{field->address, field->words(), {field}});
  }
  return spans;
}

std::int64_t DecodeCount(const RegisterField& field, const std::uint16_t* words) {
  if (field.words() == 1) {
    const std::uint16_t raw = words[0];
    return field.is_signed ? static_cast<std::int64_t>(static_cast<std::int16_t>(raw)) : raw;
  }
  const std::uint32_t raw = field.word_order == WordOrder::kHighFirst ? JoinWords(words[0], words[1])
                                                                       : JoinWords(words[1], words[0]);
  return field.is_signed ? static_cast<std::int64_t>(static_cast<std::int32_t>(raw)) : raw;
}

bool EncodeCount(const RegisterField& field, std::int64_t count, std::uint16_t* words) {
  const std::int64_t clamped = std::clamp(count, field.MinCount(), field.MaxCount());
  if (field.words() == 1) {
    words[0] = static_cast<std::uint16_t>(static_cast<std::uint64_t>(clamped) & 0xFFFFU);
  } else {
    const auto raw = static_cast<std::uint32_t>(static_cast<std::uint64_t>(clamped) & 0xFFFFFFFFU);
    words[field.word_order == WordOrder::kHighFirst ? 0 : 1] = HighWord(raw);
    words[field.word_order == WordOrder::kHighFirst ? 1 : 0] = LowWord(raw);
  }
  return clamped == count;
}

std::int64_t CounterUnwrapper::Update(std::int64_t count) {
  const std::int64_t modulus = std::int64_t{1} << width_bits_;
  if (!last_) {
    last_ = count;
    extended_ = count;
    return extended_;
  }
  // The step modulo the counter's range, taken in (-range/2, range/2].
  std::int64_t step = (count - *last_) % modulus;
  if (step < 0) step += modulus;
  if (step > modulus / 2) step -= modulus;
  extended_ += step;
  last_ = count;
  return extended_;
}

}  // namespace mosaicloc::io
