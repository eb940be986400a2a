# SPDX-License-Identifier: Apache-2.0
"""erg.open_run: a run's snapshots (CF-conventions netCDF-4/HDF5, see
README "Outputs") as one xarray.Dataset over (time, y, x)."""
import glob
import os


def snapshot_files(path):
    """The snapshot files of `path`, in step order: a run folder (its
    snapshots/), a folder of fetched snapshots, or one .h5 file."""
    if os.path.isfile(path):
        return [path]
    if not os.path.isdir(path):
        raise FileNotFoundError("%s: no such run folder or snapshot" % path)
    folder = os.path.join(path, "snapshots")
    if not os.path.isdir(folder):
        folder = path
    # step_NNNNNNNN.h5: zero-padded, so names sort by step.
    files = sorted(glob.glob(os.path.join(glob.escape(folder), "step_*.h5")))
    if not files:
        raise FileNotFoundError("%s: no snapshot (step_*.h5) in %s" % (path, folder))
    return files


def open_run(path):
    """The run at `path` (a run folder written by `erg run`/ergd, a folder
    of `erg fetch`/Client.fetch snapshots, or one snapshot file) as an
    xarray.Dataset: layers (sand, bedrock, ...) over (time, y, x), x and y
    the cell centres in metres, time the model time in days. Needs xarray,
    h5netcdf and dask (pip install ./client/python[xarray])."""
    import xarray as xr

    files = snapshot_files(path)
    return xr.open_mfdataset(files, engine="h5netcdf", combine="by_coords")
