#pragma once
// The limits on what input may ask for, checked before anything is built or allocated
// (docs/hardening.md, Limits). Each refusal names the value, the limit and where it was given.

#include <cstdint>

namespace volpar {

/// Lengths [m]: sizes, radii, spacings, positions, plane offsets, mesh coordinates (after scaling).
inline constexpr double kMaxLength = 1e6;
/// Speeds [m/s], angular speeds [rad/s] and gravity [m/s^2].
inline constexpr double kMaxSpeed = 1e6;
/// Scene files [bytes] (a scene of a million explicit particles is about 40 MiB).
inline constexpr std::uintmax_t kMaxSceneFileBytes = std::uintmax_t{64} << 20;
/// Mesh (OBJ) files [bytes].
inline constexpr std::uintmax_t kMaxMeshFileBytes = std::uintmax_t{256} << 20;
/// Nesting of lists and maps in a scene file (a scene needs about six).
inline constexpr int kMaxSceneNesting = 64;

}  // namespace volpar
