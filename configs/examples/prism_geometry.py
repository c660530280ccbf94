#!/usr/bin/env python3
"""Coordinates and rest lengths of the explicit prisms in configs/examples/.

A regular n-strut prism (Kenner's simplex for n = 3): bottom ring of radius r at z = 0,
top ring of the same radius at z = h, twisted by 90° + 180°/n (the twist at which the
prism has a self-stress state); strut i joins bottom node i to top node i, vertical cable
i joins bottom node i to top node i + n − 1. The self-stress state is the null vector of
the equilibrium matrix, scaled so that the bottom ring cables carry `--ring-force`; each
member's rest length then follows from its law, l0 = l / (1 + N/EA), so that the given
shape is in equilibrium with that prestress (to the printed digits; tsim re-balances it).

Prints the `nodes:` and `members:` YAML (indented for `model:`). Member groups: `ring_bottom`,
`ring_top`, `vertical` and, for the struts, the names of --strut-groups in turn (default
`strut`); --ea gives EA [N] per member group (one for each group used). The first bottom
node sits at 270° − 180°/n, so that bottom nodes 0 and 1 lie on a line parallel to x
(handy for a statically determinate 3-2-1 support). Example (configs/examples/prism_selfweight.yaml):

    prism_geometry.py --struts 3 --radius 1 --height 1.5 --ring-force 4000 \
        --ea strut=90.6e6 --ea ring_bottom=10.06e6 --ea ring_top=10.06e6 --ea vertical=10.06e6
"""

import argparse

import numpy as np


def prism(n, r, h, rot0_deg, strut_groups):
    ang = np.radians(rot0_deg) + 2 * np.pi * np.arange(n) / n
    twist = np.radians(90 + 180 / n)
    bottom = np.c_[r * np.cos(ang), r * np.sin(ang), np.zeros(n)]
    top = np.c_[r * np.cos(ang + twist), r * np.sin(ang + twist), np.full(n, h)]
    members = [(f"s{i}", strut_groups[i % len(strut_groups)], i, n + i) for i in range(n)]
    members += [(f"cb{i}", "ring_bottom", i, (i + 1) % n) for i in range(n)]
    members += [(f"ct{i}", "ring_top", n + i, n + (i + 1) % n) for i in range(n)]
    members += [(f"cv{i}", "vertical", i, n + (i + n - 1) % n) for i in range(n)]
    return np.r_[bottom, top], members


def self_stress(x, members):
    a = np.zeros((x.size, len(members)))
    for k, (_, _, i, j) in enumerate(members):
        e = (x[j] - x[i]) / np.linalg.norm(x[j] - x[i])
        a[3 * i:3 * i + 3, k] -= e
        a[3 * j:3 * j + 3, k] += e
    _, s, vt = np.linalg.svd(a)
    assert s[-1] < 1e-12 * s[0], "no self-stress state at this twist"
    return vt[-1]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--struts", type=int, required=True)
    ap.add_argument("--radius", type=float, required=True, help="ring radius [m]")
    ap.add_argument("--height", type=float, required=True, help="[m]")
    ap.add_argument("--ring-force", type=float, required=True, help="prestress of the bottom ring cables [N]")
    ap.add_argument("--strut-groups", default="strut", help="comma-separated, given to the struts in turn")
    ap.add_argument("--ea", action="append", required=True, metavar="GROUP=EA")
    args = ap.parse_args()
    n = args.struts
    ea = {k: float(v) for k, v in (e.split("=") for e in args.ea)}
    x, members = prism(n, args.radius, args.height, 270 - 180 / n, args.strut_groups.split(","))
    x = np.round(x, 12) + 0.0  # no 1e-16 round-off in the printed coordinates, no −0
    q = self_stress(x, members)
    q *= args.ring_force / q[n]  # member n: the first bottom ring cable
    names = [f"b{i}" for i in range(n)] + [f"t{i}" for i in range(n)]
    print("  nodes:")
    for name, p in zip(names, x):
        print(f"    - {{ id: {name}, xyz: [{p[0]:.12g}, {p[1]:.12g}, {p[2]:.12g}] }}")
    print("  members:")
    for (mid, group, i, j), force in zip(members, q):
        length = np.linalg.norm(x[j] - x[i])
        l0 = length / (1 + force / ea[group])
        kind = "strut" if mid.startswith("s") else "cable"
        print(f"    - {{ id: {mid}, nodes: [{names[i]}, {names[j]}], kind: {kind}, groups: [{group}], "
              f"rest_length: {l0:.15g} }}  # N = {force:.6g} N, l = {length:.12g} m")


if __name__ == "__main__":
    main()
