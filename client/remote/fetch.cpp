// erg fetch ID [--step S | --all] --out DIR
// erg preview ID [--step S] --out FILE.png
// Snapshots come over StreamSnapshot into DIR/NAME.part (remote/download.h):
// resumed from the .part's size after an interruption (a lost connection is
// retried here; a killed erg resumes on its next run), checked against the
// sha256 of the first message, renamed to DIR/NAME when whole. The fetched
// paths are printed on stdout, one a line.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>

#include "commands.h"
#include "progress_bar.h"
#include "remote/args.h"
#include "remote/common.h"
#include "remote/connection.h"
#include "remote/download.h"
#include "remote/status.h"

namespace erg::client {

namespace fs = std::filesystem;

namespace {

// Downloads the snapshot of `step` into `dir`; returns the exit code.
// `connected`: ergd has answered this command already (see watch_job).
int fetch_step(Remote& remote, const std::string& id, std::int64_t step, const std::string& dir,
               bool connected) {
  // The .part to resume is looked for under ergd's usual name; when ergd
  // names the file otherwise, the stream is opened again with that name.
  std::string name = snapshot_file_name(step);
  bool existing_checked = false;
  int renamed = 0;
  RetryBudget retry;
  for (;;) {
    std::unique_ptr<PartialDownload> dl;
    try {
      dl = std::make_unique<PartialDownload>(dir, name);
    } catch (const std::exception& e) {
      std::cerr << "erg: fetch: " << e.what() << "\n";
      return kExitError;
    }
    std::error_code ec;
    // A finished file is checked against the server's sha256 first (the
    // first message carries it; the rest is not read).
    const bool check_existing = !existing_checked && fs::exists(dl->final_path(), ec);
    const std::int64_t offset = check_existing ? 0 : dl->resume_offset();

    erg::v1::StreamSnapshotRequest req;
    req.set_id(id);
    req.set_step(step);
    req.set_offset(offset);
    grpc::ClientContext ctx;
    remote.prepare(ctx);
    auto reader = remote.stub().StreamSnapshot(&ctx, req);
    erg::v1::SnapshotChunk chunk;
    auto stop = [&] {
      ctx.TryCancel();
      (void)reader->Finish();
    };
    bool got_first = reader->Read(&chunk);
    if (got_first) {
      connected = true;
      if (chunk.step() != step) {
        stop();
        std::cerr << "erg: fetch: ergd sent step " << chunk.step() << " for step " << step << "\n";
        return kExitError;
      }
      if (!is_plain_file_name(chunk.name())) {
        stop();
        std::cerr << "erg: fetch: refusing ergd's file name '" << chunk.name() << "'\n";
        return kExitError;
      }
      if (chunk.name() != name) {
        stop();
        if (++renamed > 2) {
          std::cerr << "erg: fetch: ergd keeps renaming step " << step << "\n";
          return kExitError;
        }
        name = chunk.name();
        continue;
      }
      if (check_existing) {
        stop();
        existing_checked = true;
        if (file_has_sha256(dl->final_path(), chunk.sha256())) {
          std::cerr << "erg: " << dl->final_path() << " already present and verified\n";
          std::cout << dl->final_path() << std::endl;
          return kExitOk;
        }
        std::cerr << "erg: " << dl->final_path()
                  << " differs from ergd's snapshot; downloading it again\n";
        continue;
      }
      PartialDownload::Start start;
      try {
        start = dl->start(offset, chunk.size(), chunk.sha256());
      } catch (const std::exception& e) {
        stop();
        std::cerr << "erg: fetch: " << e.what() << "\n";
        return kExitError;
      }
      if (dl->discarded())
        std::cerr << "erg: discarded " << dl->part_path()
                  << " (it belongs to another file); starting again\n";
      if (start == PartialDownload::Start::kRestart) {
        stop();
        continue;
      }
      if (offset > 0) std::cerr << "erg: resuming " << name << " at byte " << offset << "\n";
    }
    // The data.
    set_interrupt_note("interrupted; " + dl->part_path() + " is kept, erg fetch resumes it");
    ProgressBar bar;
    const double t0 = monotonic_seconds();
    double last_draw = -1;
    bool bad = false;
    if (got_first) {
      do {
        try {
          dl->append(chunk.offset(), chunk.data().data(), chunk.data().size());
        } catch (const std::exception& e) {
          bar.finish();
          std::cerr << "erg: fetch: " << e.what() << "\n";
          bad = true;
          break;
        }
        if (!chunk.data().empty()) retry.reset();
        const double now = monotonic_seconds();
        if (now - last_draw > 0.2 || dl->complete()) {
          const double rate = now > t0 ? static_cast<double>(dl->bytes() - offset) / (now - t0) : 0;
          bar.update_bytes(name, dl->bytes(), dl->size(), rate);
          last_draw = now;
        }
      } while (reader->Read(&chunk));
    }
    if (bad) {
      stop();
      return kExitError;
    }
    const grpc::Status status = reader->Finish();
    bar.finish();
    set_interrupt_note("");
    if (status.ok() && dl->complete()) {
      try {
        dl->finish();
      } catch (const std::exception& e) {
        std::cerr << "erg: fetch: " << e.what() << "\n";
        return kExitError;
      }
      std::cout << dl->final_path() << std::endl;
      return kExitOk;
    }
    if (status.error_code() == grpc::StatusCode::OUT_OF_RANGE && offset > 0) {
      // ergd cannot continue from the .part's size: start afresh.
      std::cerr << "erg: " << name << ": ergd cannot resume at byte " << offset
                << "; starting again\n";
      fs::remove(dl->part_path(), ec);
      continue;
    }
    if (!status.ok() && (!connected || !is_stream_break(static_cast<int>(status.error_code()),
                                                        status.error_message())))
      return remote.fail("fetch", status);
    // A lost stream (or one that ended early): resume from the .part.
    const double wait = retry.next_delay(monotonic_seconds());
    if (wait < 0) {
      std::cerr << "erg: fetch: gave up on " << name << " at byte "
                << (dl->size() >= 0 ? dl->bytes() : offset) << " (" << dl->part_path()
                << " is kept; erg fetch resumes it)\n";
      return status.ok() ? kExitError : remote.fail("fetch", status);
    }
    std::cerr << "erg: lost the stream of " << name << " ("
              << (status.ok() ? std::string("ended early")
                              : status_code_name(static_cast<int>(status.error_code())) + ": " +
                                    status.error_message())
              << "); retrying\n";
    sleep_seconds(wait);
  }
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
  std::vector<std::int64_t> steps;
  if (step >= 0) {
    steps.push_back(step);
  } else {
    // The latest snapshot, or all of them: named by the job's record so a
    // resumed download asks for the same file.
    erg::v1::Job job;
    int code = 0;
    if (!get_job(remote, "fetch", id, &job, &code)) return code;
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
  fs::create_directories(dir, ec);
  if (ec) {
    std::cerr << "erg: fetch: cannot create " << dir << ": " << ec.message() << "\n";
    return kExitError;
  }
  // With --step alone ergd has not answered yet.
  const bool connected = step < 0;
  for (const auto s : steps)
    if (const int code = fetch_step(remote, id, s, dir, connected); code != kExitOk) return code;
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
  // Written under a temporary name and renamed: never half a PNG.
  const std::string tmp = out + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f.write(preview.png().data(), static_cast<std::streamsize>(preview.png().size()));
    f.close();
    if (!f) {
      std::error_code ec;
      fs::remove(tmp, ec);
      std::cerr << "erg: preview: cannot write " << out << "\n";
      return kExitError;
    }
  }
  std::error_code ec;
  fs::rename(tmp, out, ec);
  if (ec) {
    fs::remove(tmp, ec);
    std::cerr << "erg: preview: cannot write " << out << ": " << ec.message() << "\n";
    return kExitError;
  }
  std::cerr << "erg: preview of step " << preview.step() << " of " << req.id() << " ("
            << fmt_bytes(static_cast<double>(preview.png().size())) << ")\n";
  std::cout << out << std::endl;
  return kExitOk;
}

}  // namespace erg::client
