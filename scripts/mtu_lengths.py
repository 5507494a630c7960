#!/usr/bin/env python3
"""The muscle-tendon lengths myo-sim's own model gives T5's muscles through
the elbow's flexion, by MuJoCo: how far each muscle's path (its sites and
wrapping geoms) stretches or shortens between the straight arm and 120°.

    pip install mujoco          # MuJoCo's Python bindings (tested: 4.0.0)
    scripts/fetch_myo_sim.sh    # the myo-sim models, once
    python3 scripts/mtu_lengths.py [--angles 0,0.5,1,1.5,2.0944]

It composes the model as T5's recipe does (assets/recipes/t5.ron: the right
arm on the torso's site arm_attach_r), sets `elbow_flexion_r` to each angle
(radians) with every other joint at 0, and prints each muscle's tendon
length over its length at the first angle. A surface drawn along a muscle's
path keeps its edges along the fibres within [×0.6, ×1.6] only where this
does (ARCHITECTURE.md, "Where those come from").
"""
import argparse
import os
import re
import sys

MUSCLES = ["TRIlong", "TRIlat", "TRImed", "ANC", "BIClong", "BICshort",
           "BRA", "BRD", "PT", "FCR", "ECRL"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--angles", default="0,0.5,1,1.5,2.0944",
                        help="elbow flexion angles in radians, the first the reference")
    args = parser.parse_args()
    angles = [float(a) for a in args.angles.split(",")]
    try:
        import mujoco
    except ImportError:
        sys.exit("mtu_lengths: needs MuJoCo's Python bindings: pip install mujoco")
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "assets", "mjcf")
    models = os.path.join(root, "myo_sim", "models")
    torso_chain = os.path.join(models, "torso", "assets", "myotorso_chain.xml")
    if not os.path.exists(torso_chain):
        sys.exit("mtu_lengths: no myo-sim models in assets/mjcf/myo_sim: run scripts/fetch_myo_sim.sh")
    # The torso chain with the arm's chain in a body at the site the
    # recipe attaches it to. MJCF includes resolve from the including
    # file's folder, so the composed chain sits beside the torso's.
    chain = open(torso_chain).read()
    site = next(line for line in chain.splitlines() if 'name="arm_attach_r"' in line)
    pos = re.search(r'pos="([^"]+)"', site).group(1)
    arm = f'<body name="arm_root_r" pos="{pos}"><include file="../../arm/assets/myoarm_r_chain.xml"/></body>'
    chain = chain.replace(site, site + "\n" + arm)
    composed_chain = os.path.join(os.path.dirname(torso_chain), f".mtu_chain_{os.getpid()}.xml")
    model_file = os.path.join(root, f".mtu_model_{os.getpid()}.xml")
    try:
        open(composed_chain, "w").write(chain)
        rel = os.path.relpath(composed_chain, root)
        open(model_file, "w").write(f"""<mujoco model="mtu">
    <include file="myo_sim/models/torso/assets/myotorso_assets.xml"/>
    <include file="myo_sim/models/head/assets/myohead_simple_assets.xml"/>
    <include file="myo_sim/models/arm/assets/myoarm_r_assets.xml"/>
    <compiler angle="radian" meshdir="myo_sim/models"/>
    <worldbody><include file="{rel}"/></worldbody>
    <include file="myo_sim/models/arm/assets/myoarm_r_tendon.xml"/>
    <include file="myo_sim/models/arm/assets/myoarm_r_muscle.xml"/>
</mujoco>""")
        model = mujoco.MjModel.from_xml_path(model_file)
    finally:
        for f in (composed_chain, model_file):
            if os.path.exists(f):
                os.remove(f)
    data = mujoco.MjData(model)
    elbow = model.joint("elbow_flexion_r").qposadr[0]
    lengths = []
    for angle in angles:
        mujoco.mj_resetData(model, data)
        data.qpos[elbow] = angle
        mujoco.mj_forward(model, data)
        lengths.append({m: data.ten_length[model.tendon(m + "_tendon").id] for m in MUSCLES})
    print("muscle    " + " ".join(f"{a:>7.3f}" for a in angles) + "   (rad; length over the first)")
    for m in MUSCLES:
        ratios = " ".join(f"{l[m] / lengths[0][m]:>7.3f}" for l in lengths)
        print(f"{m:<10}{ratios}   {lengths[0][m] * 1e3:.1f} mm at {angles[0]:g}")


if __name__ == "__main__":
    main()
