"""One picture of each style (issue 35: "preview PNGs of each style"), with the figures that
say whether the style shows: bearing entropy, straight-through share and 4-way share (to set
against the cgcc city centres of its label, bench/realism.py) and the main roads' radialness
around their best centre (``data.condition.main_road_radialness``).

Usage: python bench/style_gallery.py [--skeleton learned] [--density 60] [--seed 910000]
           [--out docs/styles.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from roadweaver_sumo.data.condition import main_road_radialness
from roadweaver_sumo.expand import expand_skeleton
from roadweaver_sumo.realism import realism_statistics
from roadweaver_sumo.roadgraph import edge_coords
from roadweaver_sumo.skeleton import make_skeleton
from roadweaver_sumo.spec import STYLES, ScenarioSpec

WIDTH = {"arterial": 1.6, "collector": 1.0, "local": 0.5}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--skeleton", default="learned")
    parser.add_argument("--density", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=910000)
    parser.add_argument("--out", type=Path, default=Path("docs/styles.png"))
    args = parser.parse_args()
    fig, axes = plt.subplots(1, len(STYLES), figsize=(5 * len(STYLES), 5.4))
    for ax, style in zip(axes, STYLES, strict=True):
        spec = ScenarioSpec(density=args.density, vehicles=1, seed=args.seed, style=style,
                            skeleton=args.skeleton)
        G = expand_skeleton(spec, make_skeleton(spec))
        s = realism_statistics(G)
        for u, v, cls in G.edges(data="road_class"):
            c = edge_coords(G, u, v)
            ax.plot(c[:, 0], c[:, 1], color="black", lw=WIDTH.get(cls, 0.5))
        figures = (f"entropy {s['bearing_entropy']:.2f}, straight "
                   f"{s['straight_through_share_inner']:.2f}, 4-way "
                   f"{s['four_way_share_inner']:.2f}\nmain-road radialness "
                   f"{main_road_radialness(G):.2f}")
        ax.set_title(f"{args.skeleton} {style}\n{figures}", fontsize=10)
        print(f"{style}: {figures.replace(chr(10), ', ')}")
        ax.set_xlim(0, spec.width)
        ax.set_ylim(0, spec.height)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"2 km maps at {args.density:g} road nodes/km², seed {args.seed}")
    fig.tight_layout(rect=(0, 0, 1, 0.94))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=60)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
