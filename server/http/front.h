// SPDX-License-Identifier: Apache-2.0
// The socket side of ergd's HTTP server, in front of cpp-httplib's routing.
//
// cpp-httplib (0.11) gives every connection a pool thread from accept to
// close and has no deadline for a whole request: a client that sends one
// header line every few seconds holds a thread for as long as it likes, and
// a handful of them starve every dashboard and /metrics request. So ergd
// reads requests itself, on one epoll thread that holds any number of slow
// connections at no cost in threads:
//   - the headers (TLS handshake included) must arrive within
//     header_timeout_s of the connection, the body within body_timeout_s
//     after them; headers are at most max_header_bytes, bodies at most
//     max_body_bytes (408, 431, 413 otherwise);
//   - a client address holds at most per_address connections at once, all
//     addresses together max_connections (further ones are closed at once);
//   - only complete requests reach the worker threads, which run the
//     handlers (httplib's routing, from memory) and hand back the answer;
//     the epoll thread writes it within write_timeout_s and closes.
// One request per connection (answers say `Connection: close`).
#pragma once

#include <openssl/ssl.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace erg::server {

struct FrontLimits {
  double header_timeout_s = 10;
  double body_timeout_s = 10;
  double write_timeout_s = 30;
  size_t max_header_bytes = 16 * 1024;
  size_t max_body_bytes = 64 * 1024;
  int per_address = 16;
  int max_connections = 4096;
  int workers = 4;
};

class HttpFront {
 public:
  // A complete request (headers and body, as received) -> the whole answer.
  using Handler = std::function<std::string(const std::string& request, int fd,
                                            const std::string& peer_ip, int peer_port)>;
  // With cert and key, connections are TLS (OpenSSL); throws on a bad pair.
  HttpFront(FrontLimits limits, Handler handler, const std::string& tls_cert,
            const std::string& tls_key);
  ~HttpFront();
  void start(const std::string& host, int port);  // throws when it cannot bind
  void stop();

 private:
  struct Conn;
  struct Done {
    std::uint64_t id;
    std::string answer;
  };
  struct Work {
    std::uint64_t id;
    std::string request;
    int fd;
    std::string ip;
    int port;
  };
  void loop();
  void worker();
  void on_accept();
  void on_event(Conn& c, std::uint32_t events);
  void read_some(Conn& c);
  void write_some(Conn& c);
  void tls_blocked_or_closed(Conn& c, ssize_t n);
  void drain(Conn& c);
  void request_complete_or_not(Conn& c);
  void answer(Conn& c, std::string text);
  void close_conn(std::uint64_t id);
  void watch(Conn& c);
  void expire(double now);

  FrontLimits lim_;
  Handler handler_;
  SSL_CTX* tls_ = nullptr;
  int listen_fd_ = -1, epoll_fd_ = -1, wake_fd_ = -1;
  std::atomic<bool> stopping_{false};
  std::thread loop_thread_;
  std::vector<std::thread> workers_;
  std::uint64_t next_id_ = 2;  // 0: the listening socket, 1: the wake-up eventfd
  std::map<std::uint64_t, std::unique_ptr<Conn>> conns_;  // epoll thread only
  std::map<std::string, int> per_address_;                // epoll thread only
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Work> work_;  // complete requests waiting for a worker
  std::deque<Done> done_;  // answers waiting for the epoll thread
};

}  // namespace erg::server
