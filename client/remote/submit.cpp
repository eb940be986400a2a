// SPDX-License-Identifier: Apache-2.0
// erg submit JOB.json [--watch] [--key K] [--steps N] [--snapshot-every K]
//                     [--checkpoint-every C] [--ranks P] [--threads T]
//                     [--partition P] [--account A] [--nodes N] [--gpus-per-node G]
//                     [--time-limit MINUTES]   (Slurm: ergd --launcher slurm)
// The job is loaded and validated here exactly as `erg run` does, the run
// overrides are erg run's (erg::job::parse_run_flags), and ergd validates it
// again with the same code.
#include <iostream>
#include <random>
#include <set>
#include <stdexcept>

#include "commands.h"
#include "job/run_flags.h"
#include "job/spec.h"
#include "remote/common.h"
#include "remote/connection.h"
#include "remote/status.h"

namespace erg::client {

namespace {

// A key for this invocation, so that a SubmitJob retried after a lost reply
// cannot queue the job twice.
std::string random_key() {
  std::random_device rd;
  char buf[40];
  std::snprintf(buf, sizeof buf, "erg-%08x%08x", rd(), rd());
  return buf;
}

}  // namespace

int cmd_submit(Remote& remote, const std::vector<std::string>& args) {
  // The run overrides shared with `erg run`; the other run flags choose
  // things ergd decides for a remote job.
  static const std::set<std::string> kRunFlags = {"--steps", "--snapshot-every",
                                                  "--checkpoint-every", "--ranks", "--threads"};
  static const std::set<std::string> kNotRemote = {"--out",   "--resume",      "--backend",
                                                   "--tiles", "--progress-fd", "--quiet"};
  bool watch = false;
  std::string key;
  // The batch-system request (erg.v1.Resources); ergd validates the values.
  std::string partition, account;
  long nodes = 0, gpus = 0, minutes = 0;
  auto integer = [&](size_t& i, const std::string& flag, long& out) {
    if (i + 1 >= args.size()) return false;
    try {
      size_t used = 0;
      out = std::stol(args[++i], &used);
      return used == args[i].size() && out >= 0;
    } catch (...) {
      return false;
    }
    (void)flag;
  };
  std::vector<std::string> run_args;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--watch") {
      watch = true;
    } else if (a == "--key") {
      if (i + 1 >= args.size()) return usage_error("submit", "--key: missing value");
      key = args[++i];
      if (key.empty() || key.size() > 128)
        return usage_error("submit", "--key: 1 to 128 characters");
    } else if (a == "--partition" || a == "--account") {
      if (i + 1 >= args.size()) return usage_error("submit", a + ": missing value");
      (a == "--partition" ? partition : account) = args[++i];
    } else if (a == "--nodes" || a == "--gpus-per-node" || a == "--time-limit") {
      long& out = a == "--nodes" ? nodes : a == "--gpus-per-node" ? gpus : minutes;
      if (!integer(i, a, out)) return usage_error("submit", a + ": expected a whole number >= 0");
    } else if (kNotRemote.count(a)) {
      return usage_error("submit", a + " is not available for a remote job (ergd chooses the "
                                       "output folder, backend and tiles)");
    } else if (kRunFlags.count(a)) {
      run_args.push_back(a);  // with its value, checked by parse_run_flags
      if (i + 1 < args.size()) run_args.push_back(args[++i]);
    } else if (a.size() > 1 && a[0] == '-') {
      return usage_error("submit", a + ": unknown flag");
    } else {
      run_args.push_back(a);
    }
  }
  // parse_run_flags wants an output folder; ergd chooses it.
  run_args.insert(run_args.end(), {"--out", "(ergd)"});
  erg::job::RunFlags flags;
  try {
    flags = erg::job::parse_run_flags(run_args);
  } catch (const std::invalid_argument& e) {
    std::string msg = e.what();
    if (const auto nl = msg.find('\n'); nl != std::string::npos) msg.erase(nl);
    return usage_error("submit", msg);
  }
  erg::v1::SubmitJobRequest req;
  try {
    erg::v1::JobSpec spec = erg::job::load_job_file(flags.job_path);
    erg::job::apply_overrides(spec, flags.overrides);
    const auto problems = erg::job::validate(spec, erg::job::base_dir_of(flags.job_path));
    if (!problems.empty()) throw erg::job::SpecError(problems);
    *req.mutable_spec() = std::move(spec);
  } catch (const erg::job::SpecError& e) {
    std::cerr << "erg: invalid job:\n" << e.what() << "\n";
    return kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "erg: submit: " << e.what() << "\n";
    return kExitUsage;
  }
  req.set_idempotency_key(key.empty() ? random_key() : key);
  req.mutable_resources()->set_ranks(flags.ranks);
  req.mutable_resources()->set_threads_per_rank(flags.threads);
  req.mutable_resources()->set_partition(partition);
  req.mutable_resources()->set_account(account);
  req.mutable_resources()->set_nodes(static_cast<int>(std::min(nodes, 1L << 30)));
  req.mutable_resources()->set_gpus_per_node(static_cast<int>(std::min(gpus, 1L << 30)));
  req.mutable_resources()->set_time_limit_minutes(static_cast<int>(std::min(minutes, 1L << 30)));

  // A call lost on the way (the connection broke after the request may have
  // reached ergd) is retried for a while: the idempotency key makes a second
  // attempt return the job the first one may have created. A server that
  // was never reached ("failed to connect") is reported at once.
  erg::v1::Job job;
  grpc::Status status;
  RetryBudget retry(10);
  for (;;) {
    grpc::ClientContext ctx;
    remote.prepare(ctx, kUnaryDeadline);
    status = remote.stub().SubmitJob(&ctx, req, &job);
    if (status.error_code() != grpc::StatusCode::UNAVAILABLE ||
        status.error_message().find("failed to connect") != std::string::npos)
      break;
    const double wait = retry.next_delay(monotonic_seconds());
    if (wait < 0) break;
    sleep_seconds(wait);
  }
  if (!status.ok()) return remote.fail("submit", status);

  std::cout << job.id() << std::endl;
  const auto& s = job.spec();
  std::cerr << "erg: submitted " << (s.name().empty() ? flags.job_path : "'" + s.name() + "'")
            << " (" << s.domain().nx() << " x " << s.domain().ny() << " cells, " << s.run().steps()
            << " steps) to " << remote.settings().server << " as " << job.id() << ", "
            << state_name(job.state()) << "\n";
  for (const auto& w : job.warnings()) std::cerr << "erg: warning: " << w << "\n";
  if (!watch) return kExitOk;
  return watch_job(remote, job.id(), "submit", true);
}

}  // namespace erg::client
