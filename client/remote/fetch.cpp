// SPDX-License-Identifier: Apache-2.0
// erg fetch ID [--step S | --all] --out DIR
// erg preview ID [--step S] --out FILE.png
// DIR becomes a run directory like erg run's (io/run_files.h): DIR/job.json
// (the job's recorded spec), DIR/snapshots/NAME with its .xdmf sidecar and
// DIR/run.xdmf, written by the worker's own XDMF code (io/io.h) from the
// fetched files, so erg export, erg amplify and ParaView take it as a local run.
// Snapshots come over StreamSnapshot into DIR/snapshots/NAME.part (remote/download.h):
// resumed from the .part's size after an interruption (a lost connection is
// retried here; a killed erg resumes on its next run), checked against the
// sha256 of the first message, renamed to DIR/NAME when whole. The fetched
// paths are printed on stdout, one a line.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>

#include "commands.h"
#include "io/atomic_file.h"
#include "io/io.h"
#include "job/spec.h"
#include "progress_bar.h"
#include "remote/args.h"
#include "remote/common.h"
#include "remote/connection.h"
#include "remote/download.h"
#include "remote/status.h"

namespace erg::client {

namespace fs = std::filesystem;

namespace {

// One StreamSnapshot call: its context, its reader and the chunk last read.
struct SnapshotStream {
  grpc::ClientContext ctx;
  std::unique_ptr<grpc::ClientReader<erg::v1::SnapshotChunk>> reader;
  erg::v1::SnapshotChunk chunk;

  SnapshotStream(Remote& remote, const std::string& id, std::int64_t step, std::int64_t offset) {
    erg::v1::StreamSnapshotRequest req;
    req.set_id(id);
    req.set_step(step);
    req.set_offset(offset);
    remote.prepare(ctx);
    reader = remote.stub().StreamSnapshot(&ctx, req);
  }
  bool read() { return reader->Read(&chunk); }
  // Ends the call early (the rest is not read).
  void stop() {
    ctx.TryCancel();
    (void)reader->Finish();
  }
};

// How one attempt at a snapshot ended: with the command's exit code, or
// with a reason to open the stream again.
struct Attempt {
  bool again = false;
  int code = kExitOk;
  static Attempt retry() { return {true, kExitOk}; }
  static Attempt exit(int code) { return {false, code}; }
};

// Downloads the snapshot of `step` into `dir`, one stream at a time until
// it is whole, verified, or cannot be had.
class StepFetch {
 public:
  // `connected`: ergd has answered this command already (see watch_job).
  StepFetch(Remote& remote, std::string id, std::int64_t step, std::string dir, bool connected)
      : remote_(remote),
        id_(std::move(id)),
        step_(step),
        dir_(std::move(dir)),
        connected_(connected),
        // The .part to resume is looked for under ergd's usual name; when
        // ergd names the file otherwise, the stream is opened again with that name.
        name_(snapshot_file_name(step)) {}

  // The file's path once run() has succeeded.
  std::string path() const { return (fs::path(dir_) / name_).string(); }

  int run() {
    for (;;) {
      const Attempt a = attempt();
      if (!a.again) return a.code;
    }
  }

 private:
  Attempt attempt() {
    std::unique_ptr<PartialDownload> dl;
    try {
      dl = std::make_unique<PartialDownload>(dir_, name_);
    } catch (const std::exception& e) {
      std::cerr << "erg: fetch: " << e.what() << "\n";
      return Attempt::exit(kExitError);
    }
    std::error_code ec;
    // A finished file is checked against the server's sha256 first (the
    // first message carries it; the rest is not read).
    const bool check_existing = !existing_checked_ && fs::exists(dl->final_path(), ec);
    const std::int64_t offset = check_existing ? 0 : dl->resume_offset();
    SnapshotStream st(remote_, id_, step_, offset);
    const bool got_first = st.read();
    if (got_first) {
      connected_ = true;
      if (const auto a = on_first_chunk(st, *dl, check_existing, offset)) return *a;
    }
    if (!receive(st, *dl, got_first, offset)) {
      st.stop();
      return Attempt::exit(kExitError);
    }
    return on_end(st, *dl, offset);
  }

  // The first message names the file and its sha256: an answer for another
  // step or file, a finished file to verify, or where the data starts.
  std::optional<Attempt> on_first_chunk(SnapshotStream& st, PartialDownload& dl,
                                        bool check_existing, std::int64_t offset) {
    const erg::v1::SnapshotChunk& chunk = st.chunk;
    if (chunk.step() != step_) {
      st.stop();
      std::cerr << "erg: fetch: ergd sent step " << chunk.step() << " for step " << step_ << "\n";
      return Attempt::exit(kExitError);
    }
    if (!is_plain_file_name(chunk.name())) {
      st.stop();
      std::cerr << "erg: fetch: refusing ergd's file name '" << chunk.name() << "'\n";
      return Attempt::exit(kExitError);
    }
    if (chunk.name() != name_) {
      st.stop();
      if (++renamed_ > 2) {
        std::cerr << "erg: fetch: ergd keeps renaming step " << step_ << "\n";
        return Attempt::exit(kExitError);
      }
      name_ = chunk.name();
      return Attempt::retry();
    }
    if (check_existing) return verify_existing(st, dl);
    return start_download(st, dl, offset);
  }

  // A file already at the final name: kept when its sha256 is ergd's.
  Attempt verify_existing(SnapshotStream& st, PartialDownload& dl) {
    st.stop();
    existing_checked_ = true;
    if (file_has_sha256(dl.final_path(), st.chunk.sha256())) {
      std::cerr << "erg: " << dl.final_path() << " already present and verified\n";
      std::cout << dl.final_path() << std::endl;
      return Attempt::exit(kExitOk);
    }
    std::cerr << "erg: " << dl.final_path()
              << " differs from ergd's snapshot; downloading it again\n";
    return Attempt::retry();
  }

  // The .part continues from `offset`, or starts afresh (then the stream
  // is opened again at 0).
  std::optional<Attempt> start_download(SnapshotStream& st, PartialDownload& dl,
                                        std::int64_t offset) {
    PartialDownload::Start start;
    try {
      start = dl.start(offset, st.chunk.size(), st.chunk.sha256());
    } catch (const std::exception& e) {
      st.stop();
      std::cerr << "erg: fetch: " << e.what() << "\n";
      return Attempt::exit(kExitError);
    }
    if (dl.discarded())
      std::cerr << "erg: discarded " << dl.part_path()
                << " (it belongs to another file); starting again\n";
    if (start == PartialDownload::Start::kRestart) {
      st.stop();
      return Attempt::retry();
    }
    if (offset > 0) std::cerr << "erg: resuming " << name_ << " at byte " << offset << "\n";
    return std::nullopt;
  }

  // The data, appended to the .part with a progress bar; false when it
  // cannot be written.
  bool receive(SnapshotStream& st, PartialDownload& dl, bool got_first, std::int64_t offset) {
    set_interrupt_note("interrupted; " + dl.part_path() + " is kept, erg fetch resumes it");
    ProgressBar bar;
    const double t0 = monotonic_seconds();
    double last_draw = -1;
    if (got_first) {
      do {
        try {
          dl.append(st.chunk.offset(), st.chunk.data().data(), st.chunk.data().size());
        } catch (const std::exception& e) {
          bar.finish();
          std::cerr << "erg: fetch: " << e.what() << "\n";
          return false;
        }
        if (!st.chunk.data().empty()) retry_.reset();
        const double now = monotonic_seconds();
        if (now - last_draw > 0.2 || dl.complete()) {
          const double rate = now > t0 ? static_cast<double>(dl.bytes() - offset) / (now - t0) : 0;
          bar.update_bytes(name_, dl.bytes(), dl.size(), rate);
          last_draw = now;
        }
      } while (st.read());
    }
    bar.finish();
    set_interrupt_note("");
    return true;
  }

  // The stream's end: the file whole, a fresh start, an error, or a break
  // to resume from after a wait.
  Attempt on_end(SnapshotStream& st, PartialDownload& dl, std::int64_t offset) {
    const grpc::Status status = st.reader->Finish();
    if (status.ok() && dl.complete()) {
      try {
        dl.finish();
      } catch (const std::exception& e) {
        std::cerr << "erg: fetch: " << e.what() << "\n";
        return Attempt::exit(kExitError);
      }
      std::cout << dl.final_path() << std::endl;
      return Attempt::exit(kExitOk);
    }
    if (status.error_code() == grpc::StatusCode::OUT_OF_RANGE && offset > 0) {
      // ergd cannot continue from the .part's size: start afresh.
      std::cerr << "erg: " << name_ << ": ergd cannot resume at byte " << offset
                << "; starting again\n";
      std::error_code ec;
      fs::remove(dl.part_path(), ec);
      return Attempt::retry();
    }
    if (!status.ok() && (!connected_ || !is_stream_break(static_cast<int>(status.error_code()),
                                                         status.error_message())))
      return Attempt::exit(remote_.fail("fetch", status));
    // A lost stream (or one that ended early): resume from the .part.
    const double wait = retry_.next_delay(monotonic_seconds());
    if (wait < 0) {
      std::cerr << "erg: fetch: gave up on " << name_ << " at byte "
                << (dl.size() >= 0 ? dl.bytes() : offset) << " (" << dl.part_path()
                << " is kept; erg fetch resumes it)\n";
      return Attempt::exit(status.ok() ? kExitError : remote_.fail("fetch", status));
    }
    std::cerr << "erg: lost the stream of " << name_ << " ("
              << (status.ok() ? std::string("ended early")
                              : status_code_name(static_cast<int>(status.error_code())) + ": " +
                                    status.error_message())
              << "); retrying\n";
    sleep_seconds(wait);
    return Attempt::retry();
  }

  Remote& remote_;
  const std::string id_;
  const std::int64_t step_;
  const std::string dir_;
  bool connected_;
  std::string name_;
  bool existing_checked_ = false;
  int renamed_ = 0;  // times ergd named the file otherwise
  RetryBudget retry_;
};

// Fetches one snapshot into DIR/snapshots and writes its sidecar and
// DIR/run.xdmf again (so an interrupted --all leaves a collection of the
// snapshots that are whole).
int fetch_step(Remote& remote, const std::string& id, std::int64_t step, const std::string& dir,
               bool connected) {
  StepFetch f(remote, id, step, (fs::path(dir) / "snapshots").string(), connected);
  if (const int code = f.run(); code != kExitOk) return code;
  try {
    io::write_xdmf_for(f.path());
    io::write_run_xdmf(dir);
  } catch (const std::exception& e) {
    std::cerr << "erg: fetch: " << e.what() << "\n";
    return kExitError;
  }
  return kExitOk;
}

}  // namespace

int cmd_fetch(Remote& remote, const std::vector<std::string>& args) {
  std::string id, dir;
  std::int64_t step = -1;
  bool all = false;
  try {
    const auto p = parse_args(args, {"--step", "--out"}, {"--all"});
    if (p.positional.size() != 1) return usage_error("fetch", "expected one job id");
    id = p.positional[0];
    if (!p.values.count("--out")) return usage_error("fetch", "missing --out DIR");
    dir = p.values.at("--out");
    all = p.switches.count("--all") > 0;
    if (p.values.count("--step")) {
      if (all) return usage_error("fetch", "--step and --all exclude each other");
      step = parse_int_flag("--step", p.values.at("--step"), 0, 1000000000);
    }
  } catch (const std::invalid_argument& e) {
    return usage_error("fetch", e.what());
  }
  // The job's record: its spec for DIR/job.json, and the snapshots to name
  // (so a resumed download asks for the same file).
  erg::v1::Job job;
  int code = 0;
  if (!get_job(remote, "fetch", id, &job, &code)) return code;
  std::vector<std::int64_t> steps;
  if (step >= 0) {
    steps.push_back(step);
  } else {
    if (job.snapshot_steps_size() == 0) {
      std::cerr << "erg: fetch: job " << id << " has no snapshot yet (" << state_name(job.state())
                << ")\n";
      return kExitNotFound;
    }
    if (all)
      steps.assign(job.snapshot_steps().begin(), job.snapshot_steps().end());
    else
      steps.push_back(job.snapshot_steps(job.snapshot_steps_size() - 1));
  }
  std::error_code ec;
  fs::create_directories(fs::path(dir) / "snapshots", ec);
  if (ec) {
    std::cerr << "erg: fetch: cannot create " << dir << ": " << ec.message() << "\n";
    return kExitError;
  }
  try {
    io::write_file_atomic((fs::path(dir) / "job.json").string(), job::to_json(job.spec()));
  } catch (const std::exception& e) {
    std::cerr << "erg: fetch: cannot write " << e.what() << "\n";
    return kExitError;
  }
  // ergd has answered (GetJob): a broken stream is retried.
  for (const auto s : steps)
    if (const int rc = fetch_step(remote, id, s, dir, true); rc != kExitOk) return rc;
  return kExitOk;
}

int cmd_preview(Remote& remote, const std::vector<std::string>& args) {
  erg::v1::GetPreviewRequest req;
  std::string out;
  try {
    const auto p = parse_args(args, {"--step", "--out"}, {});
    if (p.positional.size() != 1) return usage_error("preview", "expected one job id");
    req.set_id(p.positional[0]);
    if (!p.values.count("--out")) return usage_error("preview", "missing --out FILE.png");
    out = p.values.at("--out");
    if (p.values.count("--step"))
      req.set_step(parse_int_flag("--step", p.values.at("--step"), 0, 1000000000));
    else
      req.set_latest(true);
  } catch (const std::invalid_argument& e) {
    return usage_error("preview", e.what());
  }
  erg::v1::Preview preview;
  grpc::ClientContext ctx;
  remote.prepare(ctx, kPreviewDeadline);
  const grpc::Status status = remote.stub().GetPreview(&ctx, req, &preview);
  if (!status.ok()) return remote.fail("preview", status);
  // Never half a PNG.
  try {
    io::write_file_atomic(out, preview.png());
  } catch (const std::exception& e) {
    std::cerr << "erg: preview: cannot write " << e.what() << "\n";
    return kExitError;
  }
  std::cerr << "erg: preview of step " << preview.step() << " of " << req.id() << " ("
            << fmt_bytes(static_cast<double>(preview.png().size())) << ")\n";
  std::cout << out << std::endl;
  return kExitOk;
}

}  // namespace erg::client
