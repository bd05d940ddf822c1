"""Parameter sweeps: a table of scene variants run as independent simulations through Dask's
distributed scheduler (Debian's python3-distributed), one row per variant in a pandas
DataFrame. A local cluster by default; any scheduler address to go beyond one machine."""

import copy
import itertools
import json
import os
import sys
import time

# The stage times are the machine's: they come back as their means over the frames (s).
_TIME_COLUMNS = ("cd", "gc", "rx", "rd")


def _variant_rows(variants):
    """A dict of key -> values (their product) or a list of dicts of overrides -> list of dicts."""
    if isinstance(variants, dict):
        keys = list(variants)
        for key in keys:
            if isinstance(variants[key], (str, bytes)) or not hasattr(variants[key], "__iter__"):
                raise ValueError(f"variants[{key!r}]: a list of values is needed")
        return [dict(zip(keys, values)) for values in itertools.product(*variants.values())]
    rows = list(variants)
    for i, row in enumerate(rows):
        if not isinstance(row, dict):
            raise ValueError(f"variants[{i}]: a dict of scene key -> value is needed")
    return rows


def apply_overrides(scene, overrides):
    """A copy of the scene dict with each override set: a key is a scene key, with dots for
    nested ones ("material.young_modulus", "integrator.dt")."""
    result = copy.deepcopy(scene)
    for dotted, value in overrides.items():
        node = result
        parts = dotted.split(".")
        for part in parts[:-1]:
            if not isinstance(node.get(part), dict):
                node[part] = {}  # a preset name (e.g. "material": "liver") becomes a table
            node = node[part]
        node[parts[-1]] = value
    return result


def run_variant(scene, overrides, scene_file=None, frames=None, keep_mesh=False):
    """Runs one variant to its end (the scene's `frames`, or `frames`) and returns its row:
    the overrides, the last frame's state, the mean stage times (s), and `error` (None, or the
    message of what went wrong: a bad key, a divergence). Never raises."""
    from ._incise import Simulation

    row = dict(overrides)
    row["error"] = None
    started = time.perf_counter()
    try:
        sim = Simulation(apply_overrides(scene, overrides), scene_file=scene_file)
        count = sim.frames if frames is None else int(frames)
        records = sim.step(count)
        last = records[-1] if records else None
        row["frames"] = sim.frame
        row["time"] = sim.time
        row["vertices"] = last.vertices if last else len(sim.positions)
        row["tets"] = last.tets if last else len(sim.tets)
        row["kinetic_energy"] = last.kinetic_energy if last else 0.0
        row["max_displacement"] = last.max_displacement if last else 0.0
        row["inverted_tets"] = sim.inverted_tets
        row["guarded_tets"] = sim.guarded_tets
        for stage in _TIME_COLUMNS:
            row[stage] = sum(getattr(r, stage) for r in records) / max(1, len(records))
        if keep_mesh:
            row["positions"] = sim.positions.copy()
            row["tets_array"] = sim.tets.copy()
    except Exception as error:  # a failed variant is a row, never the sweep's end
        row["error"] = f"{type(error).__name__}: {error}"
    row["seconds"] = time.perf_counter() - started
    return row


def _scene_dict(scene):
    if isinstance(scene, dict):
        return scene, None
    path = os.path.abspath(os.fspath(scene))
    with open(path, encoding="utf-8") as text:
        return json.load(text), path


def sweep(scene, variants, workers=2, scheduler=None, frames=None, keep_mesh=False,
          progress=True, scene_file=None):
    """Runs every variant of `scene` as an independent simulation and returns a pandas DataFrame,
    one row per variant in the order given.

    scene: a scene file's path or a dict. variants: a dict of scene key -> list of values (their
    product: {"material.young_modulus": [1e3, 3e3], "integrator.dt": [0.01, 0.02]}) or a list of
    dicts of overrides; dotted keys reach nested scene keys. workers: processes of the local
    cluster (0: run here, one after another). scheduler: a Dask scheduler address
    ("tcp://host:8786") or a distributed.Client, to run beyond this machine. frames: how many to
    step (default: each scene's `frames`). keep_mesh: add the final positions and tetrahedra.
    progress: a progress bar on stderr.

    Columns: the overrides, frames, time (s), vertices, tets, kinetic_energy (J),
    max_displacement (m), inverted_tets, guarded_tets, the mean stage times cd, gc, rx, rd (s),
    seconds (wall), and error (None, or why the variant failed: failed variants are rows and
    never take the sweep down)."""
    import pandas

    base, path = _scene_dict(scene)
    scene_file = scene_file or path
    rows = _variant_rows(variants)
    results = [None] * len(rows)
    bar = _ProgressBar(len(rows), progress)
    if workers == 0 and scheduler is None:
        for i, overrides in enumerate(rows):
            results[i] = run_variant(base, overrides, scene_file, frames, keep_mesh)
            bar.advance()
    else:
        results = _run_distributed(base, rows, scene_file, frames, keep_mesh, workers, scheduler,
                                   bar)
    bar.close()
    return pandas.DataFrame(results)


def _run_distributed(base, rows, scene_file, frames, keep_mesh, workers, scheduler, bar):
    import distributed

    own_cluster = None
    if isinstance(scheduler, distributed.Client):
        client = scheduler
    elif scheduler is not None:
        client = distributed.Client(scheduler)
    else:
        # Processes, one thread each: every simulation has its own interpreter and cores. They
        # import incise from where this one did.
        package_parent = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        paths = os.environ.get("PYTHONPATH", "").split(os.pathsep)
        if package_parent not in paths:
            os.environ["PYTHONPATH"] = os.pathsep.join([package_parent] + [p for p in paths if p])
        own_cluster = distributed.LocalCluster(n_workers=max(1, int(workers)),
                                               threads_per_worker=1, processes=True,
                                               dashboard_address=None)
        client = distributed.Client(own_cluster)
    try:
        futures = [client.submit(run_variant, base, overrides, scene_file, frames, keep_mesh,
                                 pure=False, key=f"incise-variant-{i}-{time.time_ns()}")
                   for i, overrides in enumerate(rows)]
        index = {future.key: i for i, future in enumerate(futures)}
        results = [None] * len(rows)
        for future in distributed.as_completed(futures):
            i = index[future.key]
            try:
                results[i] = future.result()
            except Exception as error:  # a worker lost: the row says so
                results[i] = dict(rows[i], error=f"{type(error).__name__}: {error}")
            bar.advance()
        return results
    finally:
        if client is not scheduler:
            client.close()
        if own_cluster is not None:
            own_cluster.close()


class _ProgressBar:
    def __init__(self, total, enabled):
        self.total, self.done, self.enabled = total, 0, enabled
        self.started = time.perf_counter()
        self._draw()

    def advance(self):
        self.done += 1
        self._draw()

    def _draw(self):
        if not self.enabled:
            return
        width = 30
        filled = width * self.done // max(1, self.total)
        elapsed = time.perf_counter() - self.started
        sys.stderr.write(f"\rsweep [{'#' * filled}{'.' * (width - filled)}] "
                         f"{self.done}/{self.total} variants, {elapsed:.1f} s")
        sys.stderr.flush()

    def close(self):
        if self.enabled:
            sys.stderr.write("\n")
