// SPDX-License-Identifier: Apache-2.0
#include "remote/connection.h"

#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "remote/status.h"

namespace erg::client {

Remote::Remote(ConnectionSettings settings) : settings_(std::move(settings)) {
  std::shared_ptr<grpc::ChannelCredentials> creds;
  if (!settings_.ca.empty()) {
    std::ifstream in(settings_.ca);
    if (!in)
      throw std::runtime_error("cannot read the CA certificate " + settings_.ca + " (from " +
                               settings_.ca_origin + ")");
    std::stringstream pem;
    pem << in.rdbuf();
    grpc::SslCredentialsOptions opts;
    opts.pem_root_certs = pem.str();
    creds = grpc::SslCredentials(opts);
  } else {
    creds = grpc::InsecureChannelCredentials();
  }
  grpc::ChannelArguments args;
  // Previews of large domains and pages of jobs (each with its spec) exceed
  // gRPC's 4 MiB default.
  args.SetMaxReceiveMessageSize(1 << 30);
  args.SetMaxSendMessageSize(64 << 20);
  // Notice a dead connection under a quiet watch (a queued job) within
  // about a minute; the watch then reconnects and resumes.
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, 60000);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 20000);
  args.SetString(GRPC_ARG_PRIMARY_USER_AGENT_STRING, std::string("erg/") + ERG_VERSION);
  channel_ = grpc::CreateCustomChannel(settings_.server, creds, args);
  stub_ = erg::v1::JobService::NewStub(channel_);
}

void Remote::prepare(grpc::ClientContext& ctx, std::chrono::seconds deadline) const {
  if (!settings_.token.empty()) ctx.AddMetadata("authorization", "Bearer " + settings_.token);
  if (deadline.count() > 0) ctx.set_deadline(std::chrono::system_clock::now() + deadline);
}

int Remote::fail(const std::string& command, const grpc::Status& status) const {
  const int code = static_cast<int>(status.error_code());
  if (status.error_code() == grpc::StatusCode::UNAVAILABLE) {
    std::cerr << "erg: cannot reach ergd at " << settings_.server << " (" << status.error_message()
              << "; server from " << settings_.server_origin << ")\n";
    if (settings_.ca.empty() && status.error_message().find("Socket closed") != std::string::npos)
      std::cerr << "erg: if ergd serves TLS, give its CA certificate (--ca FILE, ERG_CA or `ca =` "
                   "in the config file)\n";
    return kExitError;
  }
  std::cerr << "erg: " << command << ": " << status_code_name(code) << ": "
            << status.error_message() << "\n";
  if (status.error_code() == grpc::StatusCode::UNAUTHENTICATED && settings_.token.empty())
    std::cerr << "erg: no token given (--token, ERG_TOKEN or `token =` in the config file)\n";
  return exit_code_for_status(code);
}

namespace {
char g_note[1024];
size_t g_note_len = 0;
extern "C" void on_interrupt(int) {
  (void)!::write(STDERR_FILENO, g_note, g_note_len);
  ::_exit(130);
}
}  // namespace

void set_interrupt_note(const std::string& text) {
  if (text.empty()) {
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
    return;
  }
  // Off a progress bar's line first; prepared here, written by the handler.
  std::string line = ::isatty(STDERR_FILENO) ? "\n" : "";
  line += "erg: ";
  line += text;
  line += '\n';
  g_note_len = std::min(line.size(), sizeof g_note);
  std::memcpy(g_note, line.data(), g_note_len);
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
}

void sleep_seconds(double s) {
  if (s > 0) std::this_thread::sleep_for(std::chrono::duration<double>(s));
}

bool get_job(Remote& remote, const std::string& command, const std::string& id, erg::v1::Job* job,
             int* code) {
  erg::v1::GetJobRequest req;
  req.set_id(id);
  grpc::ClientContext ctx;
  remote.prepare(ctx, kUnaryDeadline);
  const grpc::Status status = remote.stub().GetJob(&ctx, req, job);
  if (status.ok()) return true;
  *code = remote.fail(command, status);
  return false;
}

}  // namespace erg::client
