#pragma once
// Strong index handles. A handle is a 32-bit index into a store; handles are never reused
// within a run, so a particle id means the same particle from the first step to the last.

#include <compare>
#include <cstddef>
#include <cstdint>
#include <functional>

namespace volpar {

template <class Tag>
struct Id {
  static constexpr std::uint32_t kInvalidValue = 0xffffffffu;

  std::uint32_t value = kInvalidValue;

  constexpr Id() = default;
  constexpr explicit Id(std::uint32_t v) : value(v) {}
  constexpr explicit Id(std::size_t v) : value(static_cast<std::uint32_t>(v)) {}

  [[nodiscard]] constexpr bool valid() const { return value != kInvalidValue; }
  [[nodiscard]] constexpr std::size_t index() const { return value; }
  constexpr auto operator<=>(const Id&) const = default;
};

using BodyId = Id<struct BodyTag>;
using ParticleId = Id<struct ParticleTag>;
using ConnectorId = Id<struct ConnectorTag>;
using MaterialId = Id<struct MaterialTag>;
using PlaneId = Id<struct PlaneTag>;

}  // namespace volpar

template <class Tag>
struct std::hash<volpar::Id<Tag>> {
  std::size_t operator()(const volpar::Id<Tag>& id) const noexcept { return id.value; }
};
