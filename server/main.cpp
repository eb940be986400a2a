// SPDX-License-Identifier: Apache-2.0
// ergd: the erg job service (proto/erg/v1/service.proto).
//   ergd token new TENANT [--operator] [--tokens FILE]
//   ergd --listen ADDR --http ADDR --data DIR --tokens FILE
//        [--max-running N] [--max-ranks P] [--tls-cert F --tls-key F]
//        [--cancel-grace S] [--max-job-disk BYTES] [--tenant-cell-steps N]
//        [--worker PATH] [--mpirun PATH] [--max-attempts N]
//        [--http-timeout S] [--http-per-address N] [--http-workers N]
//        [--min-free-disk BYTES] [--max-job-memory BYTES] [--max-threads N]
//        [--worker-retries N]
//        [--launcher local|slurm] [--slurm-template FILE] [--slurm-partition P]
//        [--slurm-account A] [--slurm-time-limit MINUTES] [--slurm-gpus-per-node G]
//        [--slurm-signal SECONDS]
// SIGTERM/SIGINT: stop accepting calls, ask running workers to checkpoint,
// wait for them, exit; the jobs stay RUNNING in the store and the next ergd
// resumes them. SIGKILL loses nothing either (server/scheduler/job_manager.h).
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <signal.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "api/job_service.h"
#include "api/malformed_requests.h"
#include "auth/token_cmd.h"
#include "auth/tokens.h"
#include "http/http_api.h"
#include "io/install_paths.h"
#include "launch/local_launcher.h"
#include "launch/slurm_launcher.h"
#include "metrics/metrics.h"
#include "scheduler/job_manager.h"
#include "store/job_store.h"

namespace fs = std::filesystem;

namespace {

void usage() {
  std::cerr
      << "usage: ergd token new TENANT [--operator] [--tokens FILE]   (a new token)\n"
         "       ergd --listen HOST:PORT --http HOST:PORT --data DIR --tokens FILE\n"
         "            [--max-running N (2)] [--max-ranks P (cores)]\n"
         "            [--tls-cert FILE --tls-key FILE] [--cancel-grace SECONDS (30)]\n"
         "            [--max-job-disk BYTES (0: none)] [--tenant-cell-steps N (0: none)]\n"
         "            [--worker PATH (erg-worker next to ergd)] [--mpirun PATH (mpirun)]\n"
         "            [--max-attempts N (10): restarts of a job stopped by a signal]\n"
         "            [--http-timeout S (10): to send a request's headers, and then its body]\n"
         "            [--http-per-address N (16): HTTP connections open at once per client "
         "address]\n"
         "            [--http-workers N (4): threads answering complete HTTP requests]\n"
         "            [--max-job-memory BYTES (this machine's memory): jobs whose estimate\n"
         "             (100 bytes per cell) is above are refused] [--max-threads N (cores)]\n"
         "            [--worker-retries N (3): restarts, from the newest intact checkpoint,\n"
         "             of a job whose worker died (killed, crashed)]\n"
         "            [--min-free-disk BYTES (268435456): below this much free space in\n"
         "             --data, new jobs are refused (RESOURCE_EXHAUSTED) and queued ones wait]\n"
         "            [--launcher local|slurm (local)]\n"
         "  Slurm:     [--slurm-template FILE (share/erg/slurm/ergd-job.sbatch)]\n"
         "            [--slurm-partition P] [--slurm-account A] [--slurm-time-limit MINUTES (60)]\n"
         "            [--slurm-gpus-per-node G (0)] [--slurm-signal SECONDS (120): SIGTERM\n"
         "             this long before the walltime; the job checkpoints and resumes]\n";
}

std::string read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot read " + path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::pair<std::string, int> split_host_port(const std::string& flag, const std::string& a) {
  const auto c = a.rfind(':');
  int port = -1;
  try {
    if (c != std::string::npos) port = std::stoi(a.substr(c + 1));
  } catch (...) {
  }
  if (c == std::string::npos || port < 0 || port > 65535)
    throw std::invalid_argument(flag + ": '" + a + "' is not HOST:PORT with PORT in [0, 65535]");
  return {a.substr(0, c), port};
}

// Everything ergd's flags set.
struct Options {
  std::string listen, http, data, tokens_path, cert, key, worker, mpirun = "mpirun";
  std::string launcher_kind = "local";
  erg::server::ManagerConfig cfg;
  erg::server::FrontLimits http_limits;
  erg::server::SlurmConfig slurm;
  bool help = false;
};

// The value of a numeric flag, within [lo, hi].
double number_flag(const std::string& flag, const std::string& v, double lo, double hi) {
  double x = 0;
  try {
    size_t used = 0;
    x = std::stod(v, &used);
    if (used != v.size()) throw std::invalid_argument("");
  } catch (...) {
    throw std::invalid_argument(flag + ": '" + v + "' is not a number");
  }
  if (x < lo || x > hi)
    throw std::invalid_argument(flag + ": " + v + " is out of range [" + std::to_string(lo) + ", " +
                                std::to_string(hi) + "]");
  return x;
}

// Applies one flag `a` with its value `v`.
void set_flag(Options& o, const std::string& a, const std::string& v) {
  auto number = [&](double lo, double hi) { return number_flag(a, v, lo, hi); };
  auto& cfg = o.cfg;
  auto& slurm = o.slurm;
  if (a == "--listen")
    o.listen = v;
  else if (a == "--http")
    o.http = v;
  else if (a == "--data")
    o.data = v;
  else if (a == "--tokens")
    o.tokens_path = v;
  else if (a == "--tls-cert")
    o.cert = v;
  else if (a == "--tls-key")
    o.key = v;
  else if (a == "--worker")
    o.worker = v;
  else if (a == "--mpirun")
    o.mpirun = v;
  else if (a == "--max-running")
    cfg.max_running = static_cast<int>(number(1, 10000));
  else if (a == "--max-ranks")
    cfg.max_ranks = static_cast<int>(number(1, 1e6));
  else if (a == "--cancel-grace")
    cfg.cancel_grace_s = number(0, 86400);
  else if (a == "--max-job-disk")
    cfg.max_job_disk_bytes = static_cast<std::int64_t>(number(0, 1e18));
  else if (a == "--tenant-cell-steps")
    cfg.tenant_cell_steps = number(0, 1e30);
  else if (a == "--max-job-memory")
    cfg.max_job_memory_bytes = static_cast<std::int64_t>(number(1, 1e18));
  else if (a == "--max-threads")
    cfg.max_threads = static_cast<int>(number(1, 1e6));
  else if (a == "--worker-retries")
    cfg.worker_retries = static_cast<int>(number(0, 1000));
  else if (a == "--min-free-disk")
    cfg.min_free_disk_bytes = static_cast<std::int64_t>(number(0, 1e18));
  else if (a == "--max-attempts")
    cfg.max_attempts = static_cast<int>(number(1, 1000));
  else if (a == "--http-timeout")
    o.http_limits.header_timeout_s = o.http_limits.body_timeout_s = number(0.1, 3600);
  else if (a == "--http-per-address")
    o.http_limits.per_address = static_cast<int>(number(1, 100000));
  else if (a == "--http-workers")
    o.http_limits.workers = static_cast<int>(number(1, 256));
  else if (a == "--launcher") {
    if (v != "local" && v != "slurm")
      throw std::invalid_argument("--launcher: '" + v + "' is not local or slurm");
    o.launcher_kind = v;
  } else if (a == "--slurm-template")
    slurm.template_path = v;
  else if (a == "--slurm-partition")
    slurm.partition = v;
  else if (a == "--slurm-account")
    slurm.account = v;
  else if (a == "--slurm-time-limit")
    slurm.time_limit_minutes = static_cast<int>(number(1, 525600));
  else if (a == "--slurm-gpus-per-node")
    slurm.gpus_per_node = static_cast<int>(number(0, 64));
  else if (a == "--slurm-signal")
    slurm.signal_s = static_cast<int>(number(10, 86400));
  else
    throw std::invalid_argument("unknown flag " + a);
}

// The flags that go together or exclude each other.
void check_flags(const Options& o) {
  if (o.listen.empty() || o.data.empty() || o.tokens_path.empty())
    throw std::invalid_argument("--listen, --data and --tokens are required");
  if (o.cert.empty() != o.key.empty())
    throw std::invalid_argument("--tls-cert and --tls-key go together");
  for (const std::string* name : {&o.slurm.partition, &o.slurm.account})
    if (name->find_first_not_of(
            "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_.-") !=
        std::string::npos)
      throw std::invalid_argument("--slurm-partition/--slurm-account: '" + *name +
                                  "' is not a Slurm name (A-Z a-z 0-9 _ . -)");
  if (o.slurm.signal_s >= o.slurm.time_limit_minutes * 60)
    throw std::invalid_argument("--slurm-signal: " + std::to_string(o.slurm.signal_s) +
                                " s must be shorter than --slurm-time-limit (" +
                                std::to_string(o.slurm.time_limit_minutes) + " min)");
}

// Throws std::invalid_argument naming the flag at fault.
Options parse_flags(int argc, char** argv) {
  Options o;
  o.slurm.template_path = erg::io::shipped_file("slurm/ergd-job.sbatch", ERG_SLURM_TEMPLATE);
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      o.help = true;
      return o;
    }
    if (i + 1 >= argc) throw std::invalid_argument(a + ": needs a value");
    set_flag(o, a, argv[++i]);
  }
  check_flags(o);
  return o;
}

// erg-worker next to ergd, else erg-worker on PATH.
std::string default_worker() {
  return erg::io::sibling_program("erg-worker");
}

// Signals go to one thread (sigwait); every other thread, and the workers
// ergd starts (they unblock them), never see them asynchronously.
sigset_t block_stop_signals() {
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGTERM);
  sigaddset(&sigs, SIGINT);
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);
  signal(SIGPIPE, SIG_IGN);
  return sigs;
}

std::unique_ptr<erg::server::Launcher> make_launcher(Options& o) {
  if (o.launcher_kind == "slurm") {
    o.slurm.worker = fs::absolute(o.worker).string();
    o.slurm.mpirun = o.mpirun;
    return std::make_unique<erg::server::SlurmLauncher>(o.slurm);
  }
  return std::make_unique<erg::server::LocalLauncher>(o.worker, o.mpirun);
}

// The gRPC server of `service` on --listen, serving (health: SERVING).
std::unique_ptr<grpc::Server> start_grpc(const Options& o, erg::server::JobService& service) {
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  std::shared_ptr<grpc::ServerCredentials> creds = grpc::InsecureServerCredentials();
  if (!o.cert.empty()) {
    grpc::SslServerCredentialsOptions ssl;
    ssl.pem_key_cert_pairs.push_back({read_file(o.key), read_file(o.cert)});
    creds = grpc::SslServerCredentials(ssl);
  }
  int port = 0;
  builder.AddListeningPort(o.listen, creds, &port);
  builder.SetMaxReceiveMessageSize(4 << 20);  // specs are bounded far below this
  builder.SetMaxSendMessageSize(4 << 20);
  // Clients keep quiet streams (a watch on a queued job) alive with pings
  // every 60 s; gRPC's default would answer those with GOAWAY.
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 30000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  grpc::ResourceQuota quota("ergd");
  quota.SetMaxThreads(512);  // streams hold a thread each (watchers, downloads)
  builder.SetResourceQuota(quota);
  builder.RegisterService(&service);
  std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> hooks;
  hooks.push_back(erg::server::malformed_request_interceptor());
  builder.experimental().SetInterceptorCreators(std::move(hooks));
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) throw std::runtime_error("cannot listen on " + o.listen + " (gRPC)");
  if (auto* health = server->GetHealthCheckService())
    health->SetServingStatus("erg.v1.JobService", true);
  return server;
}

// The dashboard and /metrics on --http, if given.
std::unique_ptr<erg::server::HttpApi> start_http(const Options& o, erg::server::JobManager& manager,
                                                 erg::server::Tokens& tokens,
                                                 erg::server::Metrics& metrics) {
  if (o.http.empty()) return nullptr;
  auto [host, hport] = split_host_port("--http", o.http);
  auto web = std::make_unique<erg::server::HttpApi>(manager, tokens, metrics, o.cert, o.key,
                                                    o.http_limits);
  web->start(host, hport);
  return web;
}

// Serves until SIGTERM or SIGINT, then stops in order: no new calls,
// running workers checkpoint, ergd exits.
int serve(Options& o, const sigset_t& sigs) {
  fs::create_directories(o.data);
  o.data = fs::absolute(o.data).string();  // workers and batch scripts run elsewhere
  erg::server::Tokens tokens(o.tokens_path);
  erg::server::JobStore store((fs::path(o.data) / "ergd.sqlite").string(),
                              (fs::path(o.data) / "ergd.reserve").string());
  erg::server::Metrics metrics;
  std::unique_ptr<erg::server::Launcher> launcher = make_launcher(o);
  o.cfg.data_dir = o.data;
  erg::server::JobManager manager(store, *launcher, metrics, o.cfg);
  manager.start();
  erg::server::JobService service(manager, tokens, metrics);
  std::unique_ptr<grpc::Server> server = start_grpc(o, service);
  std::unique_ptr<erg::server::HttpApi> web = start_http(o, manager, tokens, metrics);
  std::cerr << "ergd: serving erg.v1.JobService on " << o.listen << (o.cert.empty() ? "" : " (TLS)")
            << (o.http.empty() ? "" : ", HTTP on " + o.http) << ", data in " << o.data
            << ", at most " << o.cfg.max_running << " jobs at once, " << launcher->name()
            << " launcher (" << o.worker << ")" << std::endl;

  int sig = 0;
  sigwait(&sigs, &sig);
  std::cerr << "ergd: signal " << sig << ": stopping; running jobs checkpoint and resume at the "
            << "next start" << std::endl;
  if (auto* health = server->GetHealthCheckService())
    health->SetServingStatus("erg.v1.JobService", false);
  server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  if (web) web->stop();
  manager.shutdown();
  std::cerr << "ergd: stopped" << std::endl;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 2 && std::string(argv[1]) == "token")
    return erg::server::token_command(std::vector<std::string>(argv + 2, argv + argc));
  Options o;
  try {
    o = parse_flags(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "ergd: " << e.what() << "\n";
    usage();
    return 2;
  }
  if (o.help) {
    usage();
    return 0;
  }
  if (o.worker.empty()) o.worker = default_worker();
  const sigset_t sigs = block_stop_signals();
  try {
    return serve(o, sigs);
  } catch (const std::exception& e) {
    std::cerr << "ergd: " << e.what() << std::endl;
    return 1;
  }
}
