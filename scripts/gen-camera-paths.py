#!/usr/bin/env python3
"""Writes the shipped camera paths, scripts/paths/{demo,dragon}-{overview,closeup,flythrough}.cam.

Run from the repository root; the output is committed, so this only needs to run
again when the paths change. Format: docs in common/camera/ms_camera_path.h.
"""
import argparse
import math

# No arguments: --help prints the docstring, anything else is refused (exit 2).
argparse.ArgumentParser(description=__doc__,
                        formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()

MAGIC = "meshstream-camera-path 1"


def write(name, comment, keys):
    with open(f"scripts/paths/{name}.cam", "w") as f:
        f.write(MAGIC + "\n")
        f.write(f"# {comment}\n")
        f.write("# time  position(x y z)  target(x y z)  up(x y z)  fovy_degrees\n")
        for k in keys:
            f.write(" ".join(f"{v:.6g}" for v in k) + "\n")


def orbit(center, radius, height, up, fov, seconds, steps, axis):
    keys = []
    for i in range(steps + 1):
        a = 2 * math.pi * i / steps
        if axis == "y":  # up is +y: orbit in the xz plane
            p = (center[0] + radius * math.cos(a), center[1] + height, center[2] + radius * math.sin(a))
        else:  # up is +z: orbit in the xy plane
            p = (center[0] + radius * math.cos(a), center[1] + radius * math.sin(a), center[2] + height)
        keys.append((seconds * i / steps, *p, *center, *up, fov))
    return keys


def approach(start, detail, up, fov_start, fov_end, seconds, steps):
    keys = []
    for i in range(steps + 1):
        t = i / steps
        w = 1 - (1 - t) ** 3  # ease in: most of the travel early, then settle on the detail
        p = tuple(s + (d - s) * w for s, d in zip(start, detail[0]))
        fov = fov_start + (fov_end - fov_start) * t
        keys.append((seconds * t, *p, *detail[1], *up, fov))
    return keys


# The Stanford dragon (model units: metres, about 0.2 long, y up; head towards -x).
dragon_center = (-0.0059, 0.1250, -0.0046)
dragon_head = (-0.0922, 0.1456, 0.0003)
write("dragon-overview", "orbit around the whole dragon, 12 s",
      orbit(dragon_center, 0.35, 0.06, (0, 1, 0), 40, 12.0, 12, "y"))
write("dragon-closeup", "from the overview distance down to the scales of the head, 8 s",
      approach((-0.05, 0.20, 0.33), ((-0.112, 0.152, 0.028), dragon_head), (0, 1, 0), 40, 30, 8.0, 8))
fly = []
for i in range(11):
    t = i / 10
    x = 0.11 - 0.23 * t  # tail to head
    fly.append((10.0 * t, x, 0.19, 0.07, x - 0.04, 0.13, 0.0, 0, 1, 0, 60))
write("dragon-flythrough", "low pass along the body from the tail to the head, 10 s", fly)

# The built-in demo sculpture (meshgen; about 1.25 x 1.05 x 2.1 units, z up).
demo_center = (0.0, 0.0, -0.05)
write("demo-overview", "orbit around the whole sculpture, 12 s",
      orbit(demo_center, 3.5, 0.4, (0, 0, 1), 40, 12.0, 12, "z"))
write("demo-closeup", "from the overview distance down to the carved relief, 8 s",
      approach((3.5, 0.5, 0.4), ((0.95, 0.1, 0.2), (0.6, 0.0, 0.1)), (0, 0, 1), 40, 30, 8.0, 8))
fly = []
for i in range(13):
    a = 2 * math.pi * i / 12
    z = -0.9 + 1.7 * i / 12
    fly.append((12.0 * i / 12, 1.0 * math.cos(a), 1.0 * math.sin(a), z,
                0.0, 0.0, z + 0.05, 0, 0, 1, 60))
write("demo-flythrough", "a close spiral up the sculpture, 12 s", fly)
