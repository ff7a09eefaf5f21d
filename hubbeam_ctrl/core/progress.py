"""Progress bars on stderr for sweeps, batches and long runs (tqdm).

The bar is quiet when the caller asks for silence (``enabled=False``, e.g. under the CLI's
``--json``) and when its stream is not a terminal (pipes, log files, CI), so machine-read
output never carries progress lines.
"""

from __future__ import annotations

import sys

__all__ = ["progress_bar"]


def progress_bar(total: int, label: str, enabled: bool = True, file=None, mininterval: float = 0.5):
    """A :class:`tqdm.tqdm` bar over ``total`` work units, or a silent one.

    Parameters
    ----------
    total : int
        Number of work units (samples, grid points, runs); advance with ``bar.update(n)``
        by the number of units just finished, and finish with ``bar.close()`` (or use the
        bar as a context manager).
    label : str
        Text in front of the bar.
    enabled : bool
        False: print nothing (the bar is disabled but still accepts ``update``/``close``).
    file : file-like, optional
        Stream to draw on (default ``sys.stderr``). Nothing is drawn unless its
        ``isatty()`` is true.
    mininterval : float
        Minimum time between two redraws [s].

    Returns
    -------
    tqdm.tqdm
        The bar (``bar.disable`` says whether it is silent).

    Examples
    --------
    >>> with progress_bar(3, "demo", enabled=False) as bar:
    ...     for _ in range(3):
    ...         _ = bar.update(1)
    >>> bar.disable
    True
    """
    from tqdm import tqdm

    stream = sys.stderr if file is None else file
    isatty = getattr(stream, "isatty", None)
    quiet = not enabled or not (callable(isatty) and isatty())
    return tqdm(total=max(int(total), 1), desc=label, file=stream, disable=quiet,
                mininterval=mininterval, dynamic_ncols=True, leave=False)
