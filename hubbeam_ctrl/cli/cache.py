"""``hubbeam cache info|clear``: the build cache of the compiled backend.

Example::

    hubbeam cache info --json
    hubbeam cache clear
"""

from __future__ import annotations

import json

from hubbeam_ctrl.cli.args import Command

__all__ = []


def _options(p) -> None:
    """``hubbeam cache``'s options on its parser ``p``."""
    p.add_argument("action", choices=["info", "clear"], help="info or clear")
    p.add_argument("--json", action="store_true", help="print JSON")


def _run(args) -> int:
    """Show or clear the cache (status 0)."""
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


COMMAND = Command(
    "cache", _options, _run, beam=False, help="show or clear the build cache of the compiled backend",
    description=("The compiled backend keeps the shared libraries it builds in a cache folder ($HUBBEAM_CACHE_DIR, "
                 "else the platform's cache folder). info: the folder, the libraries and their size; clear: delete "
                 "them (they are rebuilt when next needed)."))
