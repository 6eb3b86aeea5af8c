#!/usr/bin/env python3
"""MuJoCo on the accuracy-and-speed study's scenes, written in the study's CSV layout.

Install and run (never needed by the tests or CI):

    python3 -m pip install mujoco==4.0.0 numpy
    cargo run --release --features charts --example chart    # writes docs/charts/reference_*.csv
    python3 scripts/mujoco_peer.py [--out docs/charts] [--quick]
    cargo run --release --features charts --example chart    # draws MuJoCo beside this crate

What it writes into the output directory (the chart reads both back, `examples/chart/peers.rs`):

- `peer_runs.csv`: the columns of `runs.csv` (scene, method, dt, substeps, cpu_s_per_sim_s,
  traj_err, energy_drift, max_gap, status) for the scenes MuJoCo can express: A01 (pendulum),
  the conical pendulum, A02 (parallelogram four-bar, its loop closed by a `connect` equality at
  MuJoCo's default `solref` 0.02 s and, as `-tight`, at `solref` = 2 h, the stiffest MuJoCo
  accepts, with `solimp` 0.99 0.999) and the 100-link chain with its 1:1000 end bead. Methods
  `mujoco-euler` (semi-implicit Euler, MuJoCo's default) and `mujoco-rk4`. A run at `dt` with
  `substeps` is MuJoCo at `timestep = dt / substeps`, `substeps` `mj_step` calls per frame:
  the same number of force evaluations per frame as this crate's substeps for Euler (RK4 makes
  four per step). Trajectory errors are scored against the chart's own references
  (`reference_<scene>.csv`, the same probe points every 1/30 s), energies with MuJoCo's
  `energy` flag, the CPU time over the `mj_step` calls only (one thread).
- `peer_scaling.csv` (`method,n,us_per_step`): the chain of `n` links at ratio 1, dt 1/60 as 4
  MuJoCo steps of 1/240 s (the scaling chart's setting).
- `peer_mixed.csv` (`arms,joints,us_per_step,us_per_joint`): the cost scene of
  `joint_bench --cost` (five-body arms: revolute z, spherical, cylindrical z, revolute x,
  translational) at 10 to 400 arms, Euler, 4 steps of 1/240 s per frame.

Conventions, matched to the Rust scenes: gravity 9.81 m/s^2 along -Y (MuJoCo's default is -Z),
SI units, no contacts (bodies carry inertials only), no joint damping or armature.
A04 (Bricard) and the slider-crank are not built: their loop closures need a second `connect`
along each closing hinge axis, left for later.
"""

import argparse
import csv
import math
import os
import sys
import time

try:
    import mujoco
    import numpy as np
except ImportError:
    sys.exit("mujoco_peer.py needs `python3 -m pip install mujoco==4.0.0 numpy`")

G = 9.81
OUTPUT_STEP = 1.0 / 30.0


def header(integrator, h, extra=""):
    return f"""<mujoco>
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{h!r}" gravity="0 {-G} 0" integrator="{integrator}">
    <flag energy="enable" contact="disable"/>
  </option>
  {extra}
  <worldbody>"""


def vec(v):
    return " ".join(repr(float(x)) for x in v)


# --- scenes: (xml, initial qvel, probe site, gap sites or None, energy scale, length) ---


def a01(integrator, h, tight):
    # 1 kg bob (inertia 1e-4 isotropic) 1 m from a revolute z at the origin, released horizontally
    # (bob at (1, 0, 0)).
    xml = header(integrator, h) + """
    <body name="bob" pos="0 0 0">
      <joint name="pin" type="hinge" axis="0 0 1" pos="0 0 0"/>
      <inertial pos="1 0 0" mass="1" diaginertia="1e-4 1e-4 1e-4"/>
      <site name="probe" pos="1 0 0"/>
    </body>
  </worldbody>
</mujoco>"""
    return xml, None, "probe", None, 1.0 * G * 1.0, 1.0


def conical(integrator, h, tight):
    # 1 kg bob 1 m from a grounded spherical joint, 45 deg from the vertical, in its steady
    # precession about +Y (the isotropic bob spins with the rod).
    a = math.pi / 4
    pos = (math.sin(a), -math.cos(a), 0.0)
    omega = math.sqrt(G / math.cos(a))
    xml = header(integrator, h) + f"""
    <body name="bob" pos="0 0 0">
      <joint name="ball" type="ball" pos="0 0 0"/>
      <inertial pos="{vec(pos)}" mass="1" diaginertia="1e-4 1e-4 1e-4"/>
      <site name="probe" pos="{vec(pos)}"/>
    </body>
  </worldbody>
</mujoco>"""
    # Ball joint velocity: the angular velocity in the body frame (identity at t = 0).
    scale = 0.5 * omega * omega * math.sin(a) ** 2
    return xml, [0.0, omega, 0.0], "probe", None, scale, 1.0


def a02(integrator, h, tight):
    # Three uniform 1 m, 1 kg links (transverse inertia 1/12, axial 1e-4): crank (0,0)-(0,1),
    # coupler (0,1)-(1,1), rocker (1,1)-(1,0), as a tree crank -> coupler -> rocker; the
    # rocker's ground pivot (1, 0) closed by a connect equality. B0 (the crank tip) moves at
    # 1 m/s along +X: crank -1 rad/s, coupler translating, rocker -1 rad/s.
    t = 1.0 / 12.0
    solref = f'solref="{2 * h!r} 1" solimp="0.99 0.999 0.001"' if tight else ""
    xml = header(integrator, h) + f"""
    <body name="crank" pos="0 0 0">
      <joint name="j0" type="hinge" axis="0 0 1"/>
      <inertial pos="0 0.5 0" mass="1" diaginertia="{t} 1e-4 {t}"/>
      <site name="probe" pos="0 1 0"/>
      <body name="coupler" pos="0 1 0">
        <joint name="j1" type="hinge" axis="0 0 1"/>
        <inertial pos="0.5 0 0" mass="1" diaginertia="1e-4 {t} {t}"/>
        <body name="rocker" pos="1 0 0">
          <joint name="j2" type="hinge" axis="0 0 1"/>
          <inertial pos="0 -0.5 0" mass="1" diaginertia="{t} 1e-4 {t}"/>
          <site name="close_rocker" pos="0 -1 0"/>
        </body>
      </body>
    </body>
    <site name="close_ground" pos="1 0 0"/>
  </worldbody>
  <equality>
    <connect body1="rocker" body2="world" anchor="0 -1 0" {solref}/>
  </equality>
</mujoco>"""
    # Joint rates: crank -1, coupler relative +1 (absolute 0), rocker relative -1.
    return xml, [-1.0, 1.0, -1.0], "probe", ("close_rocker", "close_ground"), 40.0733, 1.0


def chain_xml(integrator, h, n, ratio):
    # Beads of 0.01 kg (inertia m 1e-5) at the ends of n massless 0.1 m links, the last bead
    # ratio times heavier, released straight at 20 deg from the downward vertical; joint k
    # (revolute z) at bead k - 1.
    a, m, th = 0.1, 0.01, math.radians(20.0)
    d = (a * math.sin(th), -a * math.cos(th), 0.0)
    body = ""
    close = ""
    sum_md = 0.0
    for k in range(n):
        mk = m * ratio if k + 1 == n else m
        sum_md += mk * (k + 1) * a
        pos = "0 0 0" if k == 0 else vec(d)
        site = '<site name="probe" pos="%s"/>' % vec(d) if k + 1 == n else ""
        body += f"""
    <body pos="{pos}">
      <joint type="hinge" axis="0 0 1"/>
      <inertial pos="{vec(d)}" mass="{mk!r}" diaginertia="{vec([mk * 1e-5] * 3)}"/>
      {site}"""
        close += "\n    </body>"
    xml = header(integrator, h) + body + close + """
  </worldbody>
</mujoco>"""
    return xml, G * (1.0 - math.cos(th)) * sum_md


def chain(integrator, h, tight, n=100, ratio=1000.0):
    xml, scale = chain_xml(integrator, h, n, ratio)
    return xml, None, "probe", None, scale, 0.1


SCENES = {
    "a01_pendulum": (a01, 10.0),
    "conical_pendulum": (conical, 10.0),
    "a02_four_bar": (a02, 10.0),
    "chain": (chain, 2.0),
}


def load(xml, qvel):
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    if qvel is not None:
        data.qvel[:] = qvel
    mujoco.mj_forward(model, data)
    return model, data


def read_reference(out, scene):
    path = os.path.join(out, f"reference_{scene}.csv")
    if not os.path.exists(path):
        sys.exit(f"{path} is missing: run `cargo run --release --features charts --bin chart` first")
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return np.array([[float(r["x"]), float(r["y"]), float(r["z"])] for r in rows])


def run(scene, build, secs, ref, dt, substeps, integrator, tight):
    """One run: (cpu_s_per_sim_s, traj_err, energy_drift, max_gap, status)."""
    h = dt / substeps
    xml, qvel, probe, gap_sites, scale, length = build(integrator, h, tight)
    model, data = load(xml, qvel)
    probe_id = model.site(probe).id
    p0 = data.site_xpos[probe_id].copy()
    if np.max(np.abs(p0 - ref[0])) > 1e-9:
        return (0.0, math.nan, math.nan, math.nan, f"failed: start {p0} differs from the reference {ref[0]}")
    gaps = None if gap_sites is None else (model.site(gap_sites[0]).id, model.site(gap_sites[1]).id)
    e0 = data.energy[0] + data.energy[1]
    per_output = round(OUTPUT_STEP / dt) * substeps
    outputs = round(secs / OUTPUT_STEP)
    busy, traj, energy, gap, status, reached = 0.0, 0.0, 0.0, 0.0, "ok", 0
    for k in range(1, outputs + 1):
        t0 = time.perf_counter()
        mujoco.mj_step(model, data, nstep=per_output)
        busy += time.perf_counter() - t0
        reached = k
        p = data.site_xpos[probe_id]
        # energy is computed by mj_step before the integration: refresh it at this state.
        mujoco.mj_energyPos(model, data)
        mujoco.mj_energyVel(model, data)
        traj = max(traj, float(np.max(np.abs(p - ref[k]))))
        energy = max(energy, abs(data.energy[0] + data.energy[1] - e0) / scale)
        if gaps is not None:
            gap = max(gap, float(np.linalg.norm(data.site_xpos[gaps[0]] - data.site_xpos[gaps[1]])))
        if not (np.all(np.isfinite(p)) and math.isfinite(energy)):
            status = "failed: not finite"
            break
        if gap > 0.1 * length:
            status = f"failed: gap {gap:.2e} m"
            break
        if energy > 10.0:
            status = f"failed: energy error {energy:.1e}"
            break
        if scene == "a02_four_bar":
            x = data.xmat[model.body("coupler").id].reshape(3, 3)[:, 0]
            turn = abs(math.atan2(x[1], x[0]))
            if turn > 0.5:
                status = f"failed: branch switch (coupler {turn:.2f} rad)"
                break
    return (busy / max(reached * OUTPUT_STEP, 1e-12), traj, energy, gap, status)


def sweep(out, rates, substeps):
    rows = []
    for scene, (build, secs) in SCENES.items():
        ref = read_reference(out, scene)
        secs = min(secs, (len(ref) - 1) * OUTPUT_STEP)
        variants = [(i, False) for i in ("Euler", "RK4")]
        if scene == "a02_four_bar":
            variants += [(i, True) for i in ("Euler", "RK4")]
        for integrator, tight in variants:
            name = f"mujoco-{integrator.lower()}" + ("-tight" if tight else "")
            for rate in rates:
                for sub in substeps:
                    dt = 1.0 / rate
                    cpu, traj, energy, gap, status = run(
                        scene, build, secs, ref, dt, sub, integrator, tight
                    )
                    rows.append((scene, name, dt, sub, cpu, traj, energy, gap, status))
                    print(f"{scene:18s} {name:20s} 1/{rate} x{sub}: traj {traj:.2e} m, "
                          f"energy {energy:.2e}, gap {gap:.1e} m, {cpu:.2e} s/s, {status}")
    with open(os.path.join(out, "peer_runs.csv"), "w") as f:
        f.write("scene,method,dt,substeps,cpu_s_per_sim_s,traj_err,energy_drift,max_gap,status\n")
        for scene, name, dt, sub, cpu, traj, energy, gap, status in rows:
            f.write(f"{scene},{name},{dt:.8f},{sub},{cpu:.4e},{traj:.4e},{energy:.4e},{gap:.4e},"
                    f"{status.replace(',', ';')}\n")


def per_step(model, data, frames=None, budget=0.3):
    """Best of three windows of 4 steps of 1/240 s per frame (us per frame)."""
    mujoco.mj_step(model, data, nstep=40)
    t0 = time.perf_counter()
    mujoco.mj_step(model, data, nstep=4)
    one = max(time.perf_counter() - t0, 1e-7)
    frames = frames or max(3, min(2000, int(budget / 3 / one)))
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        mujoco.mj_step(model, data, nstep=4 * frames)
        best = min(best, (time.perf_counter() - t0) / frames)
    return best * 1e6


def scaling(out, ns):
    with open(os.path.join(out, "peer_scaling.csv"), "w") as f:
        f.write("method,n,us_per_step\n")
        for n in ns:
            try:
                xml, _ = chain_xml("Euler", 1.0 / 240.0, n, 1.0)
                model, data = load(xml, None)
            except Exception as e:  # MuJoCo's XML parser refuses very deep trees
                print(f"chain {n}: MuJoCo cannot load it: {e}")
                continue
            us = per_step(model, data)
            print(f"chain {n}: {us:.1f} us per step of 1/60 s ({us / n:.2f} us per joint)")
            f.write(f"mujoco-euler,{n},{us:.4e}\n")


def mixed_xml(arms):
    kinds = [
        '<joint type="hinge" axis="0 0 1" pos="{p}"/>',
        '<joint type="ball" pos="{p}"/>',
        '<joint type="slide" axis="0 0 1" pos="{p}"/><joint type="hinge" axis="0 0 1" pos="{p}"/>',
        '<joint type="hinge" axis="1 0 0" pos="{p}"/>',
        '<joint type="slide" axis="1 0 0" pos="{p}"/>',
    ]
    body = ""
    for arm in range(arms):
        x = 0.5 * arm
        prev = (0.0, 0.0, 0.0)
        close = ""
        for k, joint in enumerate(kinds):
            pivot = (x, -0.2 * k, 0.0)
            bead = (pivot[0] + 0.02, pivot[1] - 0.2, 0.01)
            rel = tuple(b - p for b, p in zip(bead, prev))
            local_pivot = tuple(p - b for p, b in zip(pivot, bead))
            body += f"""
    <body pos="{vec(rel)}">
      {joint.format(p=vec(local_pivot))}
      <inertial pos="0 0 0" mass="0.1" diaginertia="1e-3 1e-3 1e-3"/>"""
            close += "\n    </body>"
            prev = bead
        body += close
    return header("Euler", 1.0 / 240.0) + body + """
  </worldbody>
</mujoco>"""


def mixed(out, arm_counts):
    with open(os.path.join(out, "peer_mixed.csv"), "w") as f:
        f.write("arms,joints,us_per_step,us_per_joint\n")
        for arms in arm_counts:
            model, data = load(mixed_xml(arms), None)
            us = per_step(model, data)
            joints = 5 * arms
            print(f"mixed {arms} arms ({joints} joints): {us:.1f} us per step, "
                  f"{us / joints:.2f} us per joint")
            f.write(f"{arms},{joints},{us:.4e},{us / joints:.4e}\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="docs/charts")
    ap.add_argument("--quick", action="store_true", help="two rates, two substep counts")
    ap.add_argument("--only", choices=["runs", "scaling", "mixed"], help="one part only")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    print(f"mujoco {mujoco.__version__}, one thread")
    rates = [30, 60] if args.quick else [30, 60, 120, 240, 480, 960]
    substeps = [1, 2] if args.quick else [1, 2, 4, 8]
    if args.only in (None, "runs"):
        sweep(args.out, rates, substeps)
    if args.only in (None, "scaling"):
        scaling(args.out, [10, 30, 100, 300, 1000])
    if args.only in (None, "mixed"):
        mixed(args.out, [10, 25, 50, 100, 200, 400])


if __name__ == "__main__":
    main()
