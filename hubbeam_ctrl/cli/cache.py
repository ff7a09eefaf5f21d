"""``hubbeam cache info|clear``: the build cache of the compiled backend.

Example::

    hubbeam cache info --json
    hubbeam cache clear
"""

from __future__ import annotations

import json

__all__ = ["add_parser", "run"]


def add_parser(subparsers, common) -> None:
    """Add the ``cache`` subcommand (``common`` is not used: the cache has no parameters).

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``hubbeam`` subcommands to add to.
    common : argparse.ArgumentParser
        Parent parser with the common plant options.
    """
    p = subparsers.add_parser(
        "cache", help="show or clear the build cache of the compiled backend",
        description=("The compiled backend keeps the shared libraries it builds in a cache "
                     "folder ($HUBBEAM_CACHE_DIR, else the platform's cache folder). "
                     "info: the folder, the libraries and their size; clear: delete them "
                     "(they are rebuilt when next needed)."))
    p.add_argument("action", choices=["info", "clear"], help="info or clear")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``hubbeam cache``; returns the exit status (0).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from hubbeam_ctrl.cli.args import stdout
    from hubbeam_ctrl.core.compiled import cache_info, clear_cache, find_compiler
    from hubbeam_ctrl.core.errors import HubbeamError

    sink = stdout(args)     # the result stream (sys.stdout collects native output during the run)

    if args.action == "clear":
        folder = cache_info()["folder"]
        removed = clear_cache()
        if args.json:
            print(json.dumps({"folder": folder, "removed_files": removed}), file=sink)
        else:
            print(f"removed {removed} files from {folder}", file=sink)
        return 0
    info = cache_info()
    try:
        info["compiler"] = " ".join(find_compiler())
    except HubbeamError as exc:
        info["compiler"] = None
        info["compiler_problem"] = str(exc)
    if args.json:
        print(json.dumps(info), file=sink)
        return 0
    print(f"cache folder: {info['folder']}", file=sink)
    print(f"C compiler:   {info['compiler'] or info['compiler_problem']}", file=sink)
    print(f"libraries:    {info['libraries']} ({info['bytes'] / 1e6:.1f} MB)", file=sink)
    for e in info["entries"]:
        funcs = ", ".join(f"{f} ({o})" for f, o in zip(e["functions"], e["flags"])) or "?"
        print(f"  {e['file']}: {e['bytes'] / 1e3:.0f} kB, {funcs}", file=sink)
    return 0
