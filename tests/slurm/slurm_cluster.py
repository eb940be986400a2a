# SPDX-License-Identifier: Apache-2.0
"""A one-node Slurm cluster (Debian's slurmctld, slurmd and munge) inside a
test's temporary directory (docs/design.md, "Platform notes"): its own munge key and
socket, state, spool and log folders, free ports; jobs run as root. stop()
cancels every job and stops every daemon it started."""
import os
import signal
import socket
import subprocess
import time


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class SlurmCluster:
    def __init__(self, root):
        self.root = root
        for d in ("munge", "state", "spool", "log"):
            os.makedirs(os.path.join(root, d), exist_ok=True)
        self.conf = os.path.join(root, "slurm.conf")
        self.env = dict(os.environ, SLURM_CONF=self.conf)
        self.host = subprocess.run(["hostname", "-s"], capture_output=True, text=True,
                                   check=True).stdout.strip()
        self.pids = []

    def _path(self, *p):
        return os.path.join(self.root, *p)

    def start(self):
        key, sock = self._path("munge", "munge.key"), self._path("munge", "munge.sock")
        subprocess.run(["mungekey", "-c", "-f", "-k", key], check=True, capture_output=True)
        os.chmod(key, 0o600)
        subprocess.run(["munged", "--force", "--key-file=" + key, "--socket=" + sock,
                        "--pid-file=" + self._path("munge", "munged.pid"),
                        "--log-file=" + self._path("munge", "munged.log"),
                        "--seed-file=" + self._path("munge", "munged.seed")],
                       check=True, capture_output=True)
        ctl_port, d_port = _free_port(), _free_port()
        with open(self.conf, "w") as f:
            f.write("""ClusterName=ergtest
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={ctl_port}
SlurmdPort={d_port}
AuthType=auth/munge
AuthInfo=socket={sock}
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation={root}/state
SlurmdSpoolDir={root}/spool
SlurmctldPidFile={root}/slurmctld.pid
SlurmdPidFile={root}/slurmd.pid
SlurmctldLogFile={root}/log/slurmctld.log
SlurmdLogFile={root}/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MinJobAge=3600
KillWait=10
OverTimeLimit=0
NodeName={host} NodeAddr=127.0.0.1 CPUs={cpus} State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP OverSubscribe=FORCE:4
""".format(host=self.host, ctl_port=ctl_port, d_port=d_port, sock=sock, root=self.root,
                       cpus=os.cpu_count()))
        subprocess.run(["slurmctld", "-f", self.conf], check=True, env=self.env)
        time.sleep(0.5)
        subprocess.run(["slurmd", "-f", self.conf], check=True, env=self.env)
        t0 = time.time()
        while time.time() - t0 < 60:
            out = subprocess.run(["sinfo", "-h", "-o", "%T"], capture_output=True, text=True,
                                 env=self.env).stdout.strip()
            if out in ("idle", "mixed", "allocated"):
                return self
            time.sleep(0.5)
        raise RuntimeError("slurm did not come up: " + self.logs())

    def logs(self):
        out = ""
        for name in ("log/slurmctld.log", "log/slurmd.log"):
            try:
                with open(self._path(name)) as f:
                    out += "\n== %s ==\n%s" % (name, f.read()[-3000:])
            except OSError:
                pass
        return out

    def squeue_state(self, job_id):
        return subprocess.run(["squeue", "-h", "-t", "all", "-j", str(job_id), "-o", "%T"],
                              capture_output=True, text=True, env=self.env).stdout.strip()

    def stop(self):
        subprocess.run(["scancel", "--full", "-u", "root"], capture_output=True, env=self.env)
        time.sleep(1)
        for pidfile, name in (("slurmd.pid", "slurmd"), ("slurmctld.pid", "slurmctld"),
                              ("munge/munged.pid", "munged")):
            try:
                with open(self._path(pidfile)) as f:
                    pid = int(f.read().strip())
                os.kill(pid, signal.SIGTERM)
                for _ in range(100):
                    os.kill(pid, 0)
                    time.sleep(0.1)
                os.kill(pid, signal.SIGKILL)
            except (OSError, ValueError):
                pass
