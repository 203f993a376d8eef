#pragma once
// Errors for user input and runtime trouble. Input errors carry a source location
// (file, 1-based line and column) and say what was expected. No exception crosses the step loop.

#include <cstdint>
#include <string>
#include <utility>
#include <variant>

namespace volpar {

/// A located error: `file:line:column: message`. line/column are 1-based; 0 means unknown.
struct Error {
  std::string file;
  int line = 0;
  int column = 0;
  std::string message;

  [[nodiscard]] std::string toString() const;
};

/// Either a value or an Error.
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}  // NOLINT(google-explicit-constructor)
  Result(Error error) : v_(std::move(error)) {}  // NOLINT(google-explicit-constructor)

  [[nodiscard]] bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }
  T& value() & { return std::get<0>(v_); }
  const T& value() const& { return std::get<0>(v_); }
  T&& value() && { return std::get<0>(std::move(v_)); }
  T* operator->() { return &std::get<0>(v_); }
  const T* operator->() const { return &std::get<0>(v_); }
  T& operator*() & { return std::get<0>(v_); }
  [[nodiscard]] const Error& error() const { return std::get<1>(v_); }

 private:
  std::variant<T, Error> v_;
};

/// Result of an operation that returns nothing.
using Status = Result<std::monostate>;
inline Status okStatus() { return Status(std::monostate{}); }

/// Outcome of one World::step(), a set of flags.
enum class StepStatus : std::uint32_t {
  Ok = 0,
  NonFinite = 1u << 0,  ///< a body or particle state became NaN/inf; the run must stop
};

constexpr StepStatus operator|(StepStatus a, StepStatus b) {
  return static_cast<StepStatus>(static_cast<std::uint32_t>(a) | static_cast<std::uint32_t>(b));
}
constexpr bool hasFlag(StepStatus set, StepStatus flag) {
  return (static_cast<std::uint32_t>(set) & static_cast<std::uint32_t>(flag)) != 0;
}

[[noreturn]] void assertionFailed(const char* expr, const char* file, int line, const char* message);

}  // namespace volpar

#if defined(VOLPAR_ENABLE_ASSERTS)
#define VOLPAR_ASSERT(expr, message) \
  ((expr) ? static_cast<void>(0) : ::volpar::assertionFailed(#expr, __FILE__, __LINE__, message))
#else
// (the expression is not evaluated, but its names count as used: a build without assertions warns of nothing
// that a build with them does not)
#define VOLPAR_ASSERT(expr, message) static_cast<void>(sizeof(static_cast<bool>(expr)))
#endif
