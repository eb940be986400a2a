# SPDX-License-Identifier: Apache-2.0
"""erg's Python client: jobs on an ergd (erg.Client) and runs as xarray
datasets (erg.open_run). The messages are erg.v1's (proto/erg/v1), shipped
generated in erg._proto."""
from erg._proto import job_pb2, service_pb2
from erg._proto.service_pb2 import CANCELLED, FAILED, QUEUED, RUNNING, SUCCEEDED
from erg.client import TERMINAL, Client, Error
from erg.config import resolve as resolve_settings
from erg.run import open_run

__all__ = ["Client", "Error", "open_run", "resolve_settings", "job_pb2", "service_pb2",
           "QUEUED", "RUNNING", "SUCCEEDED", "FAILED", "CANCELLED", "TERMINAL"]
__version__ = "0.1.0"
