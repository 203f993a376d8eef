#!/usr/bin/python3
"""Independent check of a volpar trajectory with h5py (no volpar code involved).

Validates the H5MD 1.1 layout documented in docs/trajectory-format.md, the consistency of the data
(rigid bodies stay rigid, centres of mass match the particles, energies add up, bodies in free flight
follow v(t) = v0 + g t, bodies created by breakage exist exactly between their steps of creation and
retirement), the contact and contact-patch records of every frame, the stored scene text and the XDMF
sidecar.

usage: validate_h5md.py FILE.h5 [--scene SCENE.yaml] [--frames N]
       validate_h5md.py --self-test FILE.h5   # damaged copies of FILE must be rejected
"""
import argparse
import os
import shutil
import sys
import tempfile
import xml.etree.ElementTree as ET

import h5py
import numpy as np


class Invalid(Exception):
    pass


def expect(cond, message):
    if not cond:
        raise Invalid(message)


def element(group, name, tail_shape, dtype_kind):
    """An H5MD time-dependent element: value [T, *tail], step [T] (int), time [T] (float)."""
    expect(name in group, f"missing element {group.name}/{name}")
    g = group[name]
    for key in ("value", "step", "time"):
        expect(key in g, f"missing {g.name}/{key}")
    value, step, time = g["value"], g["step"], g["time"]
    expect(value.shape[1:] == tuple(tail_shape), f"{value.name} has shape {value.shape}, expected [T, {tail_shape}]")
    expect(value.dtype.kind == dtype_kind, f"{value.name} has dtype {value.dtype}")
    expect(step.dtype.kind == "i" and time.dtype.kind == "f", f"{g.name} step/time types {step.dtype}/{time.dtype}")
    expect(step.shape == time.shape == (value.shape[0],), f"{g.name}: step/time/value lengths differ")
    expect(value.chunks is not None, f"{value.name} is not chunked")
    # compressed where one frame fills its chunks; chunks that fill over several frames stay uncompressed
    expect((value.compression is not None) == (value.chunks[0] == 1),
           f"{value.name}: chunks {value.chunks} with compression {value.compression}")
    return value[()], step[()], time[()]


def validate(path, scene=None, frames=None):
    f = h5py.File(path, "r")
    # /h5md
    expect("h5md" in f, "missing /h5md")
    expect(list(f["h5md"].attrs.get("version", [])) == [1, 1], "/h5md version is not [1, 1]")
    expect("name" in f["h5md/author"].attrs, "missing /h5md/author name")
    expect(f["h5md/creator"].attrs["name"] == "volpar", "creator is not volpar")
    expect(len(f["h5md/creator"].attrs["version"]) > 0, "missing creator version")
    par = f["parameters"]
    dt = float(par.attrs["dt"])
    g = np.array(par.attrs["gravity"], dtype=float)
    expect(dt > 0 and g.shape == (3,), "bad /parameters dt or gravity")

    # /particles/all
    all_ = f["particles/all"]
    expect(all_["box"].attrs["dimension"] == 3, "box dimension is not 3")
    expect([b.decode() for b in all_["box"].attrs["boundary"]] == ["none"] * 3, "box boundary is not none")
    radius = all_["radius"][()]
    mass = all_["mass"][()]
    P = radius.shape[0]
    expect(P > 0 and np.all(radius > 0) and np.all(mass > 0), "radius/mass must be positive")
    pos, step, time = element(all_, "position", (P, 3), "f")
    vel, vstep, vtime = element(all_, "velocity", (P, 3), "f")
    body, bstep, _ = element(all_, "body", (P,), "i")
    T = pos.shape[0]
    expect(T >= 1, "no frames")
    if frames is not None:
        expect(T == frames, f"{T} frames, expected {frames}")
    expect(np.all(np.diff(step) > 0), "steps not increasing")
    expect(np.allclose(time, step * dt, rtol=1e-12, atol=0), "time != step * dt")
    expect(np.array_equal(step, vstep) and np.array_equal(step, bstep), "elements sampled at different steps")
    expect(np.all(np.isfinite(pos)) and np.all(np.isfinite(vel)), "non-finite positions or velocities")

    # /particles/bodies: one row per body ever created; a row is NaN in the frames where its body does not
    # exist (not yet broken off, or already broken apart)
    bodies = f["particles/bodies"]
    names = bodies["name"][()]
    kinds = [k.decode() for k in bodies["kind"][()]]
    B = len(names)
    expect(set(kinds) <= {"rigid", "deformable", "static"}, f"unknown body kinds {set(kinds)}")
    created, retired, parent = bodies["created"][()], bodies["retired"][()], bodies["parent"][()]
    expect(created.shape == retired.shape == parent.shape == (B,), "created/retired/parent must be [B]")
    expect(np.all((parent >= -1) & (parent < np.arange(B))), "a body's parent must be an earlier body or -1")
    glued = bodies["glued_into"][()]
    expect(glued.shape == (B,) and np.all((glued == -1) | ((glued > np.arange(B)) & (glued < B))),
           "a body is glued into a later body or none (-1)")
    for b in range(B):
        if glued[b] >= 0:
            expect(retired[b] == created[glued[b]] and kinds[b] == kinds[glued[b]] == "rigid",
                   f"body {b} was glued into body {glued[b]} but did not become it")
        if parent[b] >= 0:
            expect(retired[parent[b]] == created[b], f"body {b} was created at step {created[b]}, "
                                                     f"its parent retired at {retired[parent[b]]}")
            expect(kinds[b] == kinds[parent[b]], f"body {b} has another kind than its parent")
        elif not np.any(glued == b):
            expect(created[b] == 0, f"body {b} has no parent but was created at step {created[b]}")
        expect(retired[b] == -1 or retired[b] >= created[b], f"body {b} retired before it was created")
    exists = (created[None, :] <= step[:, None]) & ((retired[None, :] < 0) | (step[:, None] < retired[None, :]))
    expect(body.min() >= 0 and body.max() < B, "particle body index out of range")
    bpos, _, _ = element(bodies, "position", (B, 3), "f")
    bq, _, _ = element(bodies, "orientation", (B, 4), "f")
    bvel, _, _ = element(bodies, "velocity", (B, 3), "f")
    bomega, _, _ = element(bodies, "angular_velocity", (B, 3), "f")
    bmass = bodies["mass"][()]
    for name, v in (("position", bpos), ("orientation", bq), ("velocity", bvel), ("angular_velocity", bomega)):
        expect(np.all(np.isfinite(v[exists])), f"body {name} not finite where the body exists")
        expect(np.all(np.isnan(v[~exists])), f"body {name} not NaN where the body does not exist")
    expect(np.allclose(np.linalg.norm(bq[exists], axis=1), 1.0, atol=1e-12), "orientations are not unit quaternions")

    def rot(q):  # w, x, y, z
        w, x, y, z = q
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])

    scale = max(1.0, float(np.abs(pos).max()))
    vscale = max(1.0, float(np.abs(vel).max()))
    for t in range(T):
        owners = np.unique(body[t])
        expect(np.all(exists[t, owners]), f"frame {t}: particles belong to a body that does not exist")
    for b in range(B):
        frames = np.nonzero(exists[:, b])[0]
        if len(frames) == 0:
            continue  # created and broken apart between two frames
        t0 = frames[0]
        idx = np.nonzero(body[t0] == b)[0]
        expect(len(idx) > 0, f"body {b} has no particles")
        expect(np.isclose(mass[idx].sum(), bmass[b], rtol=1e-12), f"body {b} mass != sum of particle masses")
        local = (pos[t0, idx] - bpos[t0, b]) @ rot(bq[t0, b])  # R^T (p - c) row-wise
        for t in frames:
            expect(np.array_equal(np.nonzero(body[t] == b)[0], idx), f"body {b} frame {t}: its particles changed")
            com = (mass[idx, None] * pos[t, idx]).sum(axis=0) / mass[idx].sum()
            expect(np.allclose(com, bpos[t, b], atol=1e-9 * scale), f"body {b} frame {t}: centre != particle mean")
            if kinds[b] == "deformable":
                continue
            # rigid: particles move with the body's pose, velocities are v + w x r
            expected = bpos[t, b] + local @ rot(bq[t, b]).T
            expect(np.allclose(pos[t, idx], expected, atol=1e-9 * scale), f"body {b} frame {t}: not rigid")
            arm = pos[t, idx] - bpos[t, b]
            expect(np.allclose(vel[t, idx], bvel[t, b] + np.cross(bomega[t, b], arm), atol=1e-9 * vscale),
                   f"body {b} frame {t}: particle velocity != v + w x r")

    # /breakage (present once something broke): one row per broken connector
    if "breakage" in f:
        br = f["breakage"]
        bs, bt = br["step"][()], br["time"][()]
        n = bs.shape[0]
        for key in ("connector", "particle_a", "particle_b", "body", "kind", "value", "mode", "energy"):
            expect(br[key].shape == (n,), f"/breakage/{key} must be [{n}]")
        expect(np.all(np.diff(bs) >= 0) and np.allclose(bt, bs * dt, rtol=1e-12), "breakage steps/times")
        expect(len(np.unique(br["connector"][()])) == n, "a connector broke twice")
        bb, bk, bv = br["body"][()], br["kind"][()], br["value"][()]
        expect(np.all((bb >= 0) & (bb < B)) and np.all(np.isin(bk, [0, 1, 2])) and np.all(np.isfinite(bv)),
               "breakage body/kind/value out of range")
        bm, be = br["mode"][()], br["energy"][()]
        # springs break by strain, rods by tension or compression, bonds by tension or shear; only bonds hold energy
        allowed = {0: (0, 1), 1: (3,), 2: (0, 2)}
        expect(all(m in allowed[k] for k, m in zip(bk, bm)), "a break's mode does not fit its connector's kind")
        expect(np.all(np.isfinite(be) & (be >= 0)) and np.all(be[bk != 2] == 0), "breakage energy out of range")
        pa, pb = br["particle_a"][()], br["particle_b"][()]
        expect(np.all((pa >= 0) & (pa < P) & (pb >= 0) & (pb < P) & (pa != pb)), "breakage particles out of range")
        for b in np.nonzero((retired >= 0) & (glued < 0))[0]:
            expect(np.any((bb == b) & (bs == retired[b])), f"body {b} broke apart at step {retired[b]} "
                                                           "without a breakage event")
    else:
        expect(np.all((retired < 0) | (glued >= 0)), "bodies broke apart but there is no /breakage group")
        bs, be = np.zeros(0, dtype=np.int64), np.zeros(0)

    # fragments: the histogram adds up to the count; every body that broke off one and exists in a frame is
    # in its bin; the breakage energy is the sum of the energies of the breaks up to the frame
    obs = f["observables"]
    fcount, fstep, _ = element(obs, "fragment_count", (), "i")
    fsizes, _, _ = element(obs, "fragment_sizes", (32,), "i")
    fmass, _, _ = element(obs, "fragment_mass", (32,), "f")
    fenergy, _, _ = element(obs, "breakage_energy", (), "f")
    lower = obs["fragment_sizes/bin_lower"][()]
    expect(np.array_equal(lower, 2 ** np.arange(32)), "fragment bins are not powers of two")
    expect(np.array_equal(fstep, step), "fragments sampled at different steps")
    expect(np.array_equal(fsizes.sum(axis=1), fcount), "fragment histogram does not add up to the fragment count")
    expect(np.all((fmass > 0) == (fsizes > 0)), "fragment mass where there are no fragments, or none where there are")
    for t in range(T):
        pieces = np.nonzero(exists[t] & (parent >= 0))[0]
        sizes = np.array([np.count_nonzero(body[t] == b) for b in pieces], dtype=np.int64)
        bins = np.bincount(np.floor(np.log2(np.maximum(sizes, 1))).astype(int), minlength=32) if len(sizes) else np.zeros(32)
        expect(np.all(bins <= fsizes[t]), f"frame {t}: bodies that broke off are missing from the fragment histogram")
        expect(np.isclose(fenergy[t], be[bs <= step[t]].sum(), rtol=1e-9, atol=1e-300),
               f"frame {t}: breakage energy != the energies of the breaks so far")

    # observables: energies add up; kinetic energy from the particles' own data where all bodies are point-like
    kin, ostep, otime = element(f["observables"], "kinetic_energy", (), "f")
    pot, _, _ = element(f["observables"], "potential_energy", (), "f")
    tot, _, _ = element(f["observables"], "total_energy", (), "f")
    element(f["observables"], "linear_momentum", (3,), "f")
    element(f["observables"], "angular_momentum", (3,), "f")
    expect(np.array_equal(ostep, step), "observables sampled at different steps")
    expect(np.all(kin >= 0), "negative kinetic energy")
    expect(np.allclose(tot, kin + pot, rtol=1e-12, atol=1e-12 * np.abs(pot).max()), "total != kinetic + potential")
    # translational kinetic energy of the bodies never exceeds the total kinetic energy
    trans = 0.5 * np.nansum(bmass[None, :] * (bvel ** 2).sum(axis=2), axis=1)
    expect(np.all(trans <= kin * (1 + 1e-9) + 1e-12), "kinetic energy below the bodies' translational energy")

    # /contacts: ragged per-frame arrays; every record agrees with the frame's positions
    cnt_obs, _, _ = element(f["observables"], "contact_count", (), "i")
    element(f["observables"], "max_penetration", (), "f")
    c = f["contacts"]
    expect(np.array_equal(c["step"][()], step), "contacts sampled at different steps")
    offset, count = c["offset"][()], c["count"][()]
    expect(offset.shape == count.shape == (T,), "contacts offset/count must be [T]")
    expect(offset[0] == 0 and np.array_equal(offset[1:], np.cumsum(count)[:-1]), "contact offsets are not cumulative")
    expect(np.array_equal(count, cnt_obs), "contact_count observable != contacts per frame")
    N = int(count.sum())
    a, b, plane = c["particle_a"][()], c["particle_b"][()], c["plane"][()]
    point, normal, depth = c["point"][()], c["normal"][()], c["depth"][()]
    expect(a.shape == b.shape == plane.shape == depth.shape == (N,) and point.shape == normal.shape == (N, 3),
           "contact arrays have inconsistent lengths")
    expect(np.all((b >= 0) != (plane >= 0)), "a contact is either a particle pair or a particle-plane contact")
    expect(np.all(depth > 0) and np.allclose(np.linalg.norm(normal, axis=1), 1.0, atol=1e-12), "bad contact depth or normal")
    planes = par["planes"][()]
    for t in range(T):
        s, e = offset[t], offset[t] + count[t]
        pa, pb = a[s:e], b[s:e]
        pair = pb >= 0
        xa = pos[t, pa]
        if pair.any():
            d = np.linalg.norm(pos[t, pb[pair]] - xa[pair], axis=1)
            expect(np.allclose(depth[s:e][pair], radius[pa[pair]] + radius[pb[pair]] - d, atol=1e-12),
                   f"frame {t}: contact depth != r_a + r_b - distance")
        if (~pair).any():
            pl = planes[plane[s:e][~pair]]
            height = (pl[:, :3] * xa[~pair]).sum(axis=1) - pl[:, 3]
            expect(np.allclose(depth[s:e][~pair], radius[pa[~pair]] - height, atol=1e-12),
                   f"frame {t}: plane contact depth != r - height")

    # /patches: the narrow phase's contact patches, ragged per-frame arrays
    patch_offset, patch_count = check_patches(f, step, exists, kinds, body, planes)

    # /parameters
    text = par["scene"][()]
    text = text.decode() if isinstance(text, bytes) else text
    if scene is not None:
        with open(scene, encoding="utf-8") as s:
            expect(s.read() == text, "stored scene text differs from the scene file")
    expect(len(par.attrs["engine_version"]) > 0, "missing engine version")
    planes = par["planes"][()]
    expect(planes.ndim == 2 and planes.shape[1] == 4, "planes must be [n, 4]")
    C, line_offset = check_connectors(f, T, P, step)

    # the XDMF sidecar, if present: the particles of every frame, the patches of every frame that has some
    side = os.path.splitext(path)[0] + ".xdmf2"
    if os.path.exists(side):
        domain = ET.parse(side).getroot().find("Domain")
        collections = {g.get("Name"): g for g in domain.findall("Grid")}
        want = {"particles", "patches"} | ({"connectors"} if C > 0 else set()) | ({"planes"} if len(planes) else set())
        expect(set(collections) == want, f"sidecar collections {sorted(collections)}, expected {sorted(want)}")
        if C > 0:
            grids = collections["connectors"].findall("Grid")
            expect(len(grids) == T, f"sidecar has {len(grids)} connector frames, file has {T}")
            for i, grid in enumerate(grids):
                expect(grid.find("Topology").get("NumberOfElements") == str(C), f"sidecar connector count of frame {i}")
                start, data = grid.find("Topology/DataItem").findall("DataItem")
                expect(data.text.strip().endswith(":/connectors/lines"), f"sidecar connector lines of frame {i}")
                expect(start.text.split() == [str(line_offset[i]), "0", "1", "1", str(C), "2"],
                       f"sidecar connector hyperslab of frame {i}")
        if len(planes):
            quad = collections["planes"]
            corners = np.array(quad.find("Geometry/DataItem").text.split(), dtype=float).reshape(-1, 4, 3)
            expect(corners.shape[0] == len(planes), "sidecar planes: one square per plane")
            for k, (n, off) in enumerate(zip(planes[:, :3], planes[:, 3])):
                expect(np.abs(corners[k] @ n - off).max() < 1e-9 * np.linalg.norm(n) * max(1.0, np.abs(corners[k]).max()),
                       f"sidecar plane {k}: corners off the plane")
        grids = collections["particles"].findall("Grid")
        expect(len(grids) == T, f"sidecar has {len(grids)} frames, file has {T}")
        for i, grid in enumerate(grids):
            expect(np.isclose(float(grid.find("Time").get("Value")), time[i], rtol=1e-15), f"sidecar time {i}")
            items = grid.find("Geometry/DataItem").findall("DataItem")
            expect(items[1].get("Dimensions") == f"{T} {P} 3", f"sidecar dimensions of frame {i}")
            expect(items[0].text.split()[0] == str(i), f"sidecar hyperslab of frame {i}")
        grids = collections["patches"].findall("Grid")
        frames_with_patches = np.nonzero(patch_count > 0)[0]
        expect(len(grids) == len(frames_with_patches),
               f"sidecar has {len(grids)} patch grids, the file {len(frames_with_patches)} frames with patches")
        rows = int(patch_count.sum())
        for i, grid in zip(frames_with_patches, grids):
            s, n = int(patch_offset[i]), int(patch_count[i])
            expect(np.isclose(float(grid.find("Time").get("Value")), time[i], rtol=1e-15), f"sidecar patch time {i}")
            expect(grid.find("Topology").get("NumberOfElements") == str(n), f"sidecar patch count of frame {i}")
            slabs = [grid.find("Geometry/DataItem")] + [a.find("DataItem") for a in grid.findall("Attribute")]
            names = [a.get("Name") for a in grid.findall("Attribute")]
            expect(names == ["normal", "depth", "case", "validated"], f"sidecar patch attributes {names}")
            for slab in slabs:
                start, data = slab.findall("DataItem")
                width = data.get("Dimensions").split()[1:]
                expect(data.get("Dimensions").split()[0] == str(rows), f"sidecar patch rows of frame {i}")
                expect(start.text.split() == [str(s)] + ["0"] * len(width) + ["1"] * (1 + len(width)) + [str(n)] + width,
                       f"sidecar patch hyperslab of frame {i}")
    f.close()
    return T, P, B


def check_connectors(f, T, P, step):
    """/connectors: every connector's particles and kind; /connectors/lines holds each frame's connectors
    with the broken ones (by /breakage, or before the first frame) drawn from particle_a to itself.
    Returns C and the per-frame offsets into /connectors/lines."""
    expect("connectors" in f, "missing /connectors")
    c = f["connectors"]
    a, b, kind, before = (c[n][()] for n in ("particle_a", "particle_b", "kind", "broken_before"))
    C = a.shape[0]
    expect(a.shape == b.shape == kind.shape == before.shape == (C,), "connector arrays of different lengths")
    expect(C == 0 or (a.min() >= 0 and b.min() >= 0 and a.max() < P and b.max() < P), "connector particle out of range")
    expect(set(np.unique(kind)) <= {0, 1, 2}, "connector kind not 0, 1 or 2")
    offset = c["lines_offset"][()]
    lines = c["lines"][()]
    expect(offset.shape == (T,), f"/connectors/lines_offset has shape {offset.shape}, expected ({T},)")
    broke = np.full(C, np.iinfo(np.int64).max)
    if "breakage" in f and f["breakage/connector"].shape[0]:
        which, when = f["breakage/connector"][()], f["breakage/step"][()]
        expect(np.all((which >= 0) & (which < C)), "/breakage/connector out of range")
        np.minimum.at(broke, which, when)
    broke[before != 0] = np.iinfo(np.int64).min
    for i in range(T):
        if C == 0:
            break
        rows = lines[offset[i]:offset[i] + C]
        expect(rows.shape == (C, 2), f"/connectors/lines of frame {i} holds {rows.shape[0]} rows, expected {C}")
        standing = broke > step[i]
        expect(np.array_equal(rows[:, 0], a) and np.array_equal(rows[:, 1], np.where(standing, b, a)),
               f"/connectors/lines of frame {i} (step {step[i]}) is not its standing connectors")
    return C, offset


def check_patches(f, step, exists, kinds, particle_body, planes):
    """/patches: one row per contact patch (one separating plane each) of every frame. Returns offset, count."""
    T, B = exists.shape
    expect("patches" in f, "missing /patches")
    p = f["patches"]
    expect(np.array_equal(p["step"][()], step) and np.array_equal(p["time"][()], f["particles/all/position/time"][()]),
           "patches sampled at different steps")
    offset, count = p["offset"][()], p["count"][()]
    expect(offset.shape == count.shape == (T,) and offset.dtype == count.dtype == np.int64,
           "patch offset/count must be int64 [T]")
    expect(offset[0] == 0 and np.array_equal(offset[1:], np.cumsum(count)[:-1]), "patch offsets are not cumulative")
    obs = f["observables"]
    expect(np.array_equal(count, obs["patch_count/value"][()]), "patch_count observable != patches per frame")
    N = int(count.sum())
    columns = {"body_a": ((N,), "i4"), "body_b": ((N,), "i4"), "plane": ((N,), "i4"), "case": ((N,), "i4"),
               "source": ((N,), "i4"), "point": ((N, 3), "f8"), "normal": ((N, 3), "f8"), "depth": ((N,), "f8"),
               "validated": ((N,), "i1"), "look_ahead": ((N,), "i1"), "look_ahead_case": ((N,), "i4"),
               "contacts": ((N,), "i4")}
    for name, (shape, dtype) in columns.items():
        d = p[name]
        expect(d.shape == shape and d.dtype == np.dtype("<" + dtype), f"/patches/{name} is {d.dtype} {d.shape}, "
                                                                     f"expected {dtype} {shape}")
        # ragged rows fill a chunk over several frames: uncompressed, rewritten in place
        expect(d.chunks is not None and d.compression is None and d.maxshape[0] is None,
               f"/patches/{name} is not chunked, uncompressed and extendible")
    expect(p["point"].attrs["unit"] == "m" and p["depth"].attrs["unit"] == "m", "patch point/depth units")
    col = {name: p[name][()] for name in columns}
    case_names = [str(n) for n in p["case"].attrs["case_names"]]
    source_names = [str(n) for n in p["source"].attrs["source_names"]]
    expect(len(case_names) > 0 and len(set(case_names)) == len(case_names), "case_names must be distinct names")
    expect(len(source_names) > 0 and len(set(source_names)) == len(source_names), "source_names must be distinct names")
    stored = obs["patches_by_case/case_names"].asstr()[()]
    expect(list(stored) == case_names, "/patches/case case_names != /observables/patches_by_case/case_names")
    case, source = col["case"], col["source"]
    expect(np.all((case >= 0) & (case < len(case_names))), "patch case outside case_names")
    expect(np.all((source >= 0) & (source < len(source_names))), "patch source outside source_names")
    expect(np.all(np.isin(col["validated"], [0, 1])) and np.all(np.isin(col["look_ahead"], [0, 1])),
           "validated/look_ahead must be 0 or 1")
    # the case the look-ahead predicted, -1 exactly where no look-ahead decided the plane
    look_case = col["look_ahead_case"]
    expect([str(n) for n in p["look_ahead_case"].attrs["case_names"]] == case_names,
           "/patches/look_ahead_case case_names != /patches/case case_names")
    expect(np.all((look_case >= -1) & (look_case < len(case_names))), "look_ahead_case outside -1 and case_names")
    expect(np.array_equal(look_case == -1, col["look_ahead"] == 0), "look_ahead_case is -1 exactly where look_ahead is 0")
    expect(np.all(np.isfinite(col["point"])) and np.all(np.isfinite(col["depth"])), "non-finite patch point or depth")
    expect(np.allclose(np.linalg.norm(col["normal"], axis=1), 1.0, rtol=0, atol=1e-12), "patch normals are not unit")
    a, b, plane = col["body_a"], col["body_b"], col["plane"]
    expect(np.all((plane >= 0) == (b == -1)), "a patch has a plane index exactly when body_b is -1")
    expect(np.all((plane >= -1) & (plane < len(planes))), "patch plane index out of range")
    expect(np.all((a >= 0) & (a < B)) and np.all((b >= -1) & (b < B)), "patch body index out of range")
    expect(np.all((b == -1) | (a <= b)), "body_a must be the body with the lower index")
    self_contact = a == b
    expect(all(kinds[i] == "deformable" for i in a[self_contact]), "a rigid or static body in contact with itself")
    plane_case = case_names.index("particle_plane") if "particle_plane" in case_names else None
    if plane_case is not None:
        expect(np.array_equal(case == plane_case, plane >= 0), "particle_plane case exactly for body-plane patches")
    expect(np.all(col["contacts"] >= 1), "a patch without contacts")
    by_case, unvalidated = obs["patches_by_case/value"][()], obs["unvalidated_patches/value"][()]
    expect(by_case.shape == (T, len(case_names)), "patches_by_case has another number of cases than case_names")
    c = f["contacts"]
    c_off, c_cnt = c["offset"][()], c["count"][()]
    c_a, c_b, c_plane = c["particle_a"][()], c["particle_b"][()], c["plane"][()]
    for t in range(T):
        s, e = offset[t], offset[t] + count[t]
        expect(np.all(exists[t, a[s:e]]) and np.all(exists[t, b[s:e][b[s:e] >= 0]]),
               f"frame {t}: a patch of a body that does not exist")
        expect(np.array_equal(np.bincount(case[s:e], minlength=len(case_names)), by_case[t]),
               f"frame {t}: patches_by_case != the patches' cases")
        expect(np.count_nonzero(col["validated"][s:e] == 0) == unvalidated[t],
               f"frame {t}: unvalidated_patches != the patches not validated")
        # the patches hold every contact the narrow phase had: the touching ones of /contacts and the
        # speculative ones (gaps) that /contacts leaves out
        expect(col["contacts"][s:e].sum() >= c_cnt[t], f"frame {t}: fewer contacts in patches than in /contacts")
        # every touching contact's body pair (or body and plane) has a patch
        keys = set(zip(a[s:e].tolist(), b[s:e].tolist(), plane[s:e].tolist()))
        cs, ce = c_off[t], c_off[t] + c_cnt[t]
        body_a = particle_body[t, c_a[cs:ce]]
        body_b = np.where(c_b[cs:ce] >= 0, particle_body[t, np.maximum(c_b[cs:ce], 0)], -1)
        lo = np.where(body_b >= 0, np.minimum(body_a, body_b), body_a)
        hi = np.where(body_b >= 0, np.maximum(body_a, body_b), -1)
        for key in set(zip(lo.tolist(), hi.tolist(), c_plane[cs:ce].tolist())):
            expect(key in keys, f"frame {t}: contacts of bodies/plane {key} but no patch")
    return offset, count


def free_flight(path):
    """In a scene without contacts every free body's velocity is v0 + g t."""
    with h5py.File(path, "r") as f:
        g = np.array(f["parameters"].attrs["gravity"])
        t = f["particles/bodies/position/time"][()]
        v = f["particles/bodies/velocity/value"][()]
        kinds = [k.decode() for k in f["particles/bodies/kind"][()]]
        for b, kind in enumerate(kinds):
            if kind == "static":
                expect(np.all(v[:, b] == 0), f"static body {b} moves")
                continue
            expected = v[0, b] + (t - t[0])[:, None] * g[None, :]
            expect(np.allclose(v[:, b], expected, atol=1e-9), f"body {b} is not in free flight")


def self_test(path):
    """Damaged copies must be rejected: proves the checks can fail."""
    validate(path)
    damages = {
        "version": lambda f: f["h5md"].attrs.__setitem__("version", np.array([1, 0], dtype=np.int32)),
        "rigidity": lambda f: f["particles/all/position/value"].__setitem__((1, 0, 0), f["particles/all/position/value"][1, 0, 0] + 1e-3),
        "time": lambda f: f["particles/all/position/time"].__setitem__(1, 123.0),
        "energy": lambda f: f["observables/total_energy/value"].__setitem__(0, f["observables/total_energy/value"][0] + 1.0),
        "body index": lambda f: f["particles/all/body/value"].__setitem__((0, 0), 999),
        "missing velocity": lambda f: f["particles/all"].__delitem__("velocity"),
        "contact offsets": lambda f: f["contacts/offset"].__setitem__(-1, f["contacts/offset"][-1] + 1),
        "body row of a missing body": lambda f: f["particles/bodies/created"].__setitem__(-1, 10 ** 9),
        "a body before it exists": lambda f: f["particles/bodies/position/value"].__setitem__((0, -1), np.zeros(3)),
        "breakage events lost": lambda f: f.__delitem__("breakage"),
        "fragment histogram": lambda f: f["observables/fragment_sizes/value"].__setitem__(
            (-1, 0), f["observables/fragment_sizes/value"][-1, 0] + 1),
        "patch normal not unit": lambda f: f["patches/normal"].__setitem__(0, f["patches/normal"][0] * 1.001),
        "patch offsets": lambda f: f["patches/offset"].__setitem__(-1, f["patches/offset"][-1] + 1),
        "patch case unknown": lambda f: f["patches/case"].__setitem__(0, len(f["patches/case"].attrs["case_names"])),
        "patch source unknown": lambda f: f["patches/source"].__setitem__(0, -1),
        "patch body out of range": lambda f: f["patches/body_a"].__setitem__(0, f["particles/bodies/created"].shape[0]),
        "patch of a body not created yet": lambda f: f["patches/body_a"].__setitem__(
            0, int(np.argmax(f["particles/bodies/created"][()]))),
        "body pair patch with a plane": lambda f: f["patches/plane"].__setitem__(
            int(np.argmax(f["patches/body_b"][()] >= 0)), 0),
        "patch contacts lost": lambda f: f["patches/contacts"].__setitem__(
            slice(None), np.ones(f["patches/contacts"].shape, dtype=np.int32)),
        "patch depth not finite": lambda f: f["patches/depth"].__setitem__(0, np.nan),
        "look-ahead case unknown": lambda f: f["patches/look_ahead_case"].__setitem__(
            0, len(f["patches/case"].attrs["case_names"])),
        "look-ahead case without a look-ahead": lambda f: f["patches/look_ahead_case"].__setitem__(
            int(np.argmin(f["patches/look_ahead"][()])), 0),
        "look-ahead without its case": lambda f: (f["patches/look_ahead"].__setitem__(0, 1),
                                                  f["patches/look_ahead_case"].__setitem__(0, -1)),
    }
    tmp = tempfile.mkdtemp()
    try:
        for name, damage in damages.items():
            copy = os.path.join(tmp, "damaged.h5")
            shutil.copy(path, copy)
            with h5py.File(copy, "r+") as f:
                damage(f)
            try:
                validate(copy)
            except (Invalid, KeyError) as e:
                print(f"rejected damaged file ({name}): {e}")
                continue
            raise SystemExit(f"self-test: damage '{name}' was not detected")
    finally:
        shutil.rmtree(tmp)
    print("self-test passed")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("file")
    ap.add_argument("--scene")
    ap.add_argument("--frames", type=int)
    ap.add_argument("--self-test", action="store_true")
    ap.add_argument("--free-flight", action="store_true", help="also check v(t) = v0 + g t for every body")
    a = ap.parse_args()
    if a.self_test:
        self_test(a.file)
        return
    try:
        T, P, B = validate(a.file, a.scene, a.frames)
        if a.free_flight:
            free_flight(a.file)
    except Invalid as e:
        print(f"{a.file}: INVALID: {e}", file=sys.stderr)
        sys.exit(1)
    print(f"{a.file}: valid H5MD 1.1 volpar trajectory ({T} frames, {P} particles, {B} bodies)")


if __name__ == "__main__":
    main()
