"""`sigmarl` command line: thin dispatch onto the library; user errors end in one message."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from sigmarl.errors import SigmarlError


def _map_names() -> list[str]:
    from sigmarl.paths import conf_dir

    return sorted(p.stem for p in (conf_dir() / "map").glob("*.yaml"))


def _resolve_map(name: str, overrides: Sequence[str]):
    """A map by config name (conf/map/<name>.yaml) or by OSM file path."""
    from sigmarl.compose import compose_config
    from sigmarl.maps import load_map

    if name.endswith(".osm") or Path(name).suffix == ".osm":
        cfg = compose_config(["map=osm", f"map.path={Path(name).resolve()}", *overrides])
    elif name in _map_names():
        cfg = compose_config([f"map={name}", *overrides])
    else:
        raise SigmarlError(f"unknown map {name!r}; known maps: {', '.join(_map_names())} (or a path to an .osm file)")
    return load_map(cfg.map)


def cmd_maps(args: argparse.Namespace) -> None:
    if args.action == "list":
        overrides = [args.map, *args.overrides] if args.map else args.overrides
        print(f"{'map':<18}{'lanelets':>9}{'routes':>8}{'size (m)':>14}{'lane width':>12}")
        for name in _map_names():
            if name == "osm":
                continue
            m = _resolve_map(name, overrides)
            w, h = m.size
            print(f"{name:<18}{len(m.lanelets):>9}{len(m.routes):>8}{f'{w:.2f} x {h:.2f}':>14}{m.lane_width:>12.2f}")
        return
    if not args.map:
        raise SigmarlError("sigmarl maps show needs a map name, e.g. `sigmarl maps show cpm`")
    from sigmarl.maps.plot import save_map_figure

    m = _resolve_map(args.map, args.overrides)
    out = Path(args.out or f"{m.name}.png")
    save_map_figure(m, out, show_ids=args.ids)
    print(f"wrote {out}")


def cmd_train(args: argparse.Namespace) -> None:
    from sigmarl.compose import compose_config
    from sigmarl.training import train

    result = train(compose_config(args.overrides))
    best = "n/a" if result.best_reward is None else f"{result.best_reward:.2f}"
    state = "finished" if result.finished else "stopped (resume with resume=true)"
    print(f"{state} after {result.iterations} iterations; best mean episode reward {best}; "
          f"checkpoints in {result.run_dir}" + (f"; MLflow run {result.run_id}" if result.run_id else ""))


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sigmarl",
        description="The SigmaRL observation-design ablation study: maps, environment, MAPPO training, evaluation, report.",
    )
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    maps = sub.add_parser("maps", help="list road maps or draw one to PNG")
    maps.add_argument("action", choices=["list", "show"])
    maps.add_argument("map", nargs="?", help="map name (see `sigmarl maps list`) or an .osm file")
    maps.add_argument("--out", help="PNG file to write (default: <map>.png)")
    maps.add_argument("--ids", action="store_true", help="label lanelet ids")
    maps.add_argument("overrides", nargs="*", default=[], help="Hydra overrides, e.g. map.lane_width=0.25")
    maps.set_defaults(func=cmd_maps)
    train = sub.add_parser("train", help="train one model with MAPPO (resumable, tracked in MLflow)")
    train.add_argument(
        "overrides", nargs="*", default=[],
        help="Hydra overrides, e.g. obs=no_ego_view seed=3 ppo=smoke resume=true",
    )
    train.set_defaults(func=cmd_train)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        args.func(args)
    except SigmarlError as e:
        print(f"sigmarl: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("sigmarl: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
