#pragma once

#include <stdexcept>
#include <string>
#include <utility>
#include <variant>

namespace mosaicloc::core {

/// What went wrong, for the caller to decide: bad input (a file, key, value or register
/// the user supplied: fix the input) or a runtime failure (I/O, a device, a library).
enum class ErrorKind { kInvalidInput, kRuntime };

/// The one exception type for startup problems: bad configuration, unreadable or corrupt
/// files, a missing device. The message names the file and line, key or register and says
/// what to do. Per-frame failures do not throw: they come back as a Result.
class Error : public std::runtime_error {
 public:
  Error(ErrorKind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  ErrorKind kind() const { return kind_; }

 private:
  ErrorKind kind_;
};

/// Shorthands for the two kinds.
[[noreturn]] void ThrowInvalidInput(const std::string& message);
[[noreturn]] void ThrowRuntime(const std::string& message);

/// The reason an operation that may fail in normal operation did not produce a value.
/// `E` is a module's own reason type (usually an enum plus diagnostics).
template <typename E>
struct Failure {
  E reason;
};

/// A value of type T or a failure of type E. Built for the frame loop, where nothing throws:
/// expected failures (no match, no convergence, a timeout) are values, not exceptions.
template <typename T, typename E = std::string>
class Result {
 public:
  Result(T value) : state_(std::move(value)) {}                       // NOLINT: implicit by design
  Result(Failure<E> failure) : state_(std::move(failure)) {}          // NOLINT: implicit by design

  bool ok() const { return std::holds_alternative<T>(state_); }
  explicit operator bool() const { return ok(); }

  /// The value; calling it on a failure is a programming error and throws std::logic_error.
  const T& value() const {
    if (!ok()) throw std::logic_error("Result::value() called on a failure");
    return std::get<T>(state_);
  }
  T& value() {
    if (!ok()) throw std::logic_error("Result::value() called on a failure");
    return std::get<T>(state_);
  }
  /// The failure reason; calling it on a success throws std::logic_error.
  const E& error() const {
    if (ok()) throw std::logic_error("Result::error() called on a success");
    return std::get<Failure<E>>(state_).reason;
  }

 private:
  std::variant<T, Failure<E>> state_;
};

/// Builds a Failure, e.g. `return Fail(std::string("no texture"));`.
template <typename E>
Failure<E> Fail(E reason) {
  return Failure<E>{std::move(reason)};
}

}  // namespace mosaicloc::core
