// SPDX-License-Identifier: Apache-2.0
// erg watch ID: follows WatchJob with a progress bar, printing the job's
// state changes, snapshots, steering events and notes as lines. A lost
// stream is opened again after the last event id seen (ergd replays what
// was missed); the command ends with the job.
#include <iostream>
#include <sstream>

#include "commands.h"
#include "progress_bar.h"
#include "remote/common.h"
#include "remote/connection.h"
#include "remote/status.h"

namespace erg::client {

int watch_job(Remote& remote, const std::string& id, const std::string& command, bool connected) {
  set_interrupt_note("stopped watching; " + id + " goes on (erg watch " + id +
                     " follows it again, erg cancel " + id + " stops it)");
  ProgressBar bar;
  std::int64_t last_id = 0;
  erg::v1::JobState final_state = erg::v1::JOB_STATE_UNSPECIFIED;
  erg::v1::Progress last_progress;
  RetryBudget retry;
  bool reported_loss = false;
  while (final_state == erg::v1::JOB_STATE_UNSPECIFIED) {
    erg::v1::WatchJobRequest req;
    req.set_id(id);
    req.set_after_event_id(last_id);
    grpc::ClientContext ctx;
    remote.prepare(ctx);  // no deadline: a job runs as long as it runs
    auto reader = remote.stub().WatchJob(&ctx, req);
    erg::v1::JobEvent ev;
    while (reader->Read(&ev)) {
      connected = true;
      if (reported_loss) {
        bar.note("erg: reconnected to ergd; resuming after event " + std::to_string(last_id));
        reported_loss = false;
      }
      retry.reset();
      if (ev.id() > last_id) last_id = ev.id();
      switch (ev.kind_case()) {
        case erg::v1::JobEvent::kProgress:
          last_progress = ev.progress();
          bar.update(ev.progress().step(), ev.progress().total_steps(), ev.progress().steps_per_s(),
                     ev.progress().eta_s());
          break;
        case erg::v1::JobEvent::kStateChanged:
          if (is_final(ev.state_changed()))
            final_state = ev.state_changed();  // summed up below
          else
            bar.note("erg: " + id + " " + state_name(ev.state_changed()) + " (" +
                     fmt_time_ms(ev.unix_ms()) + ")");
          break;
        case erg::v1::JobEvent::kSnapshotStep:
          bar.snapshot();
          bar.note("erg: snapshot at step " + std::to_string(ev.snapshot_step()));
          break;
        case erg::v1::JobEvent::kSteered: {
          erg::v1::Event shown = ev.steered();
          shown.clear_step();
          bar.note("erg: steered at step " + std::to_string(ev.steered().step()) + ": " +
                   to_json(shown, false));
          break;
        }
        case erg::v1::JobEvent::kMessage:
          bar.note("erg: " + ev.message());
          break;
        default:
          break;
      }
      if (final_state == erg::v1::JOB_STATE_UNSPECIFIED && is_final(ev.state()) &&
          ev.kind_case() != erg::v1::JobEvent::kStateChanged)
        final_state = ev.state();
      if (final_state != erg::v1::JOB_STATE_UNSPECIFIED) break;
    }
    if (final_state != erg::v1::JOB_STATE_UNSPECIFIED) {
      ctx.TryCancel();  // the stream ends here anyway
      (void)reader->Finish();
      break;
    }
    const grpc::Status status = reader->Finish();
    // The stream ended before the job did: open it again unless refused.
    if (!status.ok() && (!connected || !is_stream_break(static_cast<int>(status.error_code()),
                                                        status.error_message()))) {
      bar.finish();
      return remote.fail(command, status);
    }
    const double wait = retry.next_delay(monotonic_seconds());
    if (wait < 0) {
      bar.finish();
      std::cerr << "erg: " << command << ": gave up after "
                << static_cast<int>(retry.failing_for(monotonic_seconds()))
                << " s without ergd; the job goes on (erg watch " << id << " to follow it again)\n";
      return status.ok() ? kExitError : remote.fail(command, status);
    }
    if (!reported_loss && !status.ok()) {
      bar.note("erg: lost ergd at " + remote.settings().server + " (" +
               status_code_name(static_cast<int>(status.error_code())) + ": " +
               status.error_message() + "); reconnecting");
      reported_loss = true;
    }
    sleep_seconds(wait);
  }
  bar.finish();
  set_interrupt_note("");

  // The job's final record: the reason and log of a failure, snapshots.
  erg::v1::Job job;
  {
    erg::v1::GetJobRequest req;
    req.set_id(id);
    grpc::ClientContext ctx;
    remote.prepare(ctx, kUnaryDeadline);
    if (!remote.stub().GetJob(&ctx, req, &job).ok()) job.Clear();
  }
  // The record's progress, unless the stream saw a later one.
  const auto& pr = job.has_progress() && job.progress().step() >= last_progress.step()
                       ? job.progress()
                       : last_progress;
  switch (final_state) {
    case erg::v1::SUCCEEDED:
      std::cerr << "erg: " << id << " SUCCEEDED at step " << pr.step();
      if (const std::string sand = sand_text(pr, job.spec().domain().cell_size_m()); !sand.empty())
        std::cerr << "; sand " << sand;
      std::cerr << "\n";
      if (job.snapshot_steps_size() > 0)
        std::cerr << "erg: " << job.snapshot_steps_size() << " snapshot(s): erg fetch " << id
                  << " --all --out DIR\n";
      return kExitOk;
    case erg::v1::FAILED: {
      std::cerr << "erg: " << id << " FAILED at step " << pr.step() << ": "
                << (job.failure_reason().empty() ? "(no reason given)" : job.failure_reason())
                << "\n";
      std::istringstream tail(job.log_tail());
      std::string line;
      bool header = false;
      while (std::getline(tail, line)) {
        if (!header) std::cerr << "erg: the worker's last lines:\n";
        header = true;
        std::cerr << "  | " << line << "\n";
      }
      return kExitError;
    }
    default:
      std::cerr << "erg: " << id << " CANCELLED at step " << pr.step()
                << " (its last checkpoint is kept)\n";
      return kExitCancelled;
  }
}

int cmd_watch(Remote& remote, const std::vector<std::string>& args) {
  if (args.size() != 1 || (args[0].size() > 1 && args[0][0] == '-'))
    return usage_error("watch", "expected one job id");
  return watch_job(remote, args[0], "watch", false);
}

}  // namespace erg::client
