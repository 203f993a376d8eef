#pragma once
// The collision stage's part of a checkpoint (engine/core/state_archive.hpp): the contacts and patches of
// the current state, which the next step's solver uses as they are. The caches that carry over from step to
// step save themselves (NormalCache::save, NarrowPhase::saveCache); the broadphase's fat boxes are the
// world's to save (Broadphase::restoreBody).

#include <cstddef>

#include "volpar/collision/contact_patch.hpp"
#include "volpar/collision/particle_contacts.hpp"
#include "volpar/engine/core/state_archive.hpp"

namespace volpar {

/// Puts `contacts` under "contacts/...".
void saveContacts(StateArchive& archive, const ContactSet& contacts);
/// Reads them back into `out`, checking every particle, body and plane index against the world's counts.
bool restoreContacts(StateReader& reader, ContactSet& out, std::size_t particles, std::size_t bodies, std::size_t planes);

/// Puts `patches` under "patches/..." (their statistics included).
void savePatches(StateArchive& archive, const PatchSet& patches);
/// Reads them back into `out`, checking them against `contacts` and the world's counts.
bool restorePatches(StateReader& reader, PatchSet& out, const ContactSet& contacts, std::size_t bodies, std::size_t planes);

}  // namespace volpar
