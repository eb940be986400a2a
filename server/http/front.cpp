// SPDX-License-Identifier: Apache-2.0
#include "http/front.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <openssl/err.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>

namespace erg::server {

namespace {

double mono_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string plain_answer(int status, const char* reason, const std::string& body) {
  return "HTTP/1.1 " + std::to_string(status) + " " + reason +
         "\r\nContent-Type: text/plain\r\nContent-Length: " + std::to_string(body.size()) +
         "\r\nConnection: close\r\n\r\n" + body;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

constexpr std::uint64_t kListenId = 0, kWakeId = 1;

}  // namespace

struct HttpFront::Conn {
  std::uint64_t id = 0;
  int fd = -1;
  SSL* ssl = nullptr;
  std::string ip;
  int port = 0;
  enum State { kReading, kProcessing, kWriting, kDraining } state = kReading;
  bool linger = false;  // answered before the whole request was read
  std::string in, out;
  size_t out_pos = 0;
  size_t header_end = 0;  // bytes of headers (with the blank line), 0: not yet
  size_t need = 0;        // header_end + Content-Length
  double deadline = 0;
  bool want_read = true, want_write = false;  // what the next I/O waits for
  std::uint32_t watching = 0;                 // the events registered with epoll
};

HttpFront::HttpFront(FrontLimits limits, Handler handler, const std::string& cert,
                     const std::string& key)
    : lim_(limits), handler_(std::move(handler)) {
  if (cert.empty()) return;
  tls_ = SSL_CTX_new(TLS_server_method());
  if (!tls_ || SSL_CTX_set_min_proto_version(tls_, TLS1_2_VERSION) != 1 ||
      SSL_CTX_use_certificate_chain_file(tls_, cert.c_str()) != 1 ||
      SSL_CTX_use_PrivateKey_file(tls_, key.c_str(), SSL_FILETYPE_PEM) != 1 ||
      SSL_CTX_check_private_key(tls_) != 1) {
    if (tls_) SSL_CTX_free(tls_);
    tls_ = nullptr;
    throw std::runtime_error("HTTP server: bad TLS certificate or key (" + cert + ", " + key + ")");
  }
  SSL_CTX_set_mode(tls_, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
}

HttpFront::~HttpFront() {
  stop();
  if (tls_) SSL_CTX_free(tls_);
}

void HttpFront::start(const std::string& host_in, int port) {
  // "[::1]" as in a URL is the address ::1.
  std::string host = host_in;
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  addrinfo hints{}, *res = nullptr;
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  const std::string where = host_in + ":" + std::to_string(port);
  if (::getaddrinfo(host.empty() ? nullptr : host.c_str(), std::to_string(port).c_str(), &hints,
                    &res) != 0 ||
      !res)
    throw std::runtime_error("cannot listen on " + where + " (HTTP): unknown host");
  // The first address of the name that can be bound (a name may have several).
  std::string why = "no address";
  for (addrinfo* ai = res; ai && listen_fd_ < 0; ai = ai->ai_next) {
    const int fd = ::socket(ai->ai_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) {
      why = std::strerror(errno);
      continue;
    }
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (::bind(fd, ai->ai_addr, ai->ai_addrlen) == 0 && ::listen(fd, 1024) == 0) {
      listen_fd_ = fd;
    } else {
      why = std::strerror(errno);
      ::close(fd);
    }
  }
  ::freeaddrinfo(res);
  if (listen_fd_ < 0) throw std::runtime_error("cannot listen on " + where + " (HTTP): " + why);
  epoll_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.u64 = kListenId;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, listen_fd_, &ev);
  ev.data.u64 = kWakeId;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, wake_fd_, &ev);
  for (int i = 0; i < std::max(1, lim_.workers); ++i) workers_.emplace_back([this] { worker(); });
  loop_thread_ = std::thread([this] { loop(); });
}

void HttpFront::stop() {
  if (stopping_.exchange(true)) return;
  cv_.notify_all();
  if (wake_fd_ >= 0) {
    const std::uint64_t one = 1;
    (void)!::write(wake_fd_, &one, sizeof one);
  }
  if (loop_thread_.joinable()) loop_thread_.join();
  for (auto& t : workers_) t.join();
  workers_.clear();
  while (!conns_.empty()) close_conn(conns_.begin()->first);
  for (int* fd : {&listen_fd_, &epoll_fd_, &wake_fd_})
    if (*fd >= 0) {
      ::close(*fd);
      *fd = -1;
    }
}

void HttpFront::worker() {
  for (;;) {
    Work w;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return stopping_ || !work_.empty(); });
      if (stopping_) return;
      w = std::move(work_.front());
      work_.pop_front();
    }
    std::string answer;
    try {
      answer = handler_(w.request, w.fd, w.ip, w.port);
    } catch (const std::exception& e) {
      answer = plain_answer(500, "Internal Server Error", std::string(e.what()) + "\n");
    }
    {
      std::lock_guard lock(mu_);
      done_.push_back({w.id, std::move(answer)});
    }
    const std::uint64_t one = 1;
    (void)!::write(wake_fd_, &one, sizeof one);
  }
}

void HttpFront::watch(Conn& c) {
  std::uint32_t want = 0;
  if (c.state != Conn::kProcessing) {
    if (c.want_read) want |= EPOLLIN;
    if (c.want_write) want |= EPOLLOUT;
  }
  if (want == c.watching) return;
  epoll_event ev{};
  ev.events = want;
  ev.data.u64 = c.id;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_MOD, c.fd, &ev);
  c.watching = want;
}

void HttpFront::close_conn(std::uint64_t id) {
  auto it = conns_.find(id);
  if (it == conns_.end()) return;
  Conn& c = *it->second;
  if (c.ssl) {
    if (c.state == Conn::kWriting && c.out_pos == c.out.size()) (void)SSL_shutdown(c.ssl);
    SSL_free(c.ssl);
  }
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, c.fd, nullptr);
  ::close(c.fd);
  if (--per_address_[c.ip] <= 0) per_address_.erase(c.ip);
  conns_.erase(it);
}

void HttpFront::on_accept() {
  for (;;) {
    sockaddr_storage sa{};
    socklen_t len = sizeof sa;
    const int fd =
        ::accept4(listen_fd_, reinterpret_cast<sockaddr*>(&sa), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return;  // EAGAIN, or out of descriptors: the next round
    char ip[INET6_ADDRSTRLEN] = "?";
    int port = 0;
    if (sa.ss_family == AF_INET) {
      auto* a = reinterpret_cast<sockaddr_in*>(&sa);
      ::inet_ntop(AF_INET, &a->sin_addr, ip, sizeof ip);
      port = ntohs(a->sin_port);
    } else if (sa.ss_family == AF_INET6) {
      auto* a = reinterpret_cast<sockaddr_in6*>(&sa);
      ::inet_ntop(AF_INET6, &a->sin6_addr, ip, sizeof ip);
      port = ntohs(a->sin6_port);
    }
    const bool over_address = per_address_[ip] >= lim_.per_address;
    if (over_address || static_cast<int>(conns_.size()) >= lim_.max_connections) {
      if (!tls_) {
        const std::string a = plain_answer(
            over_address ? 429 : 503, over_address ? "Too Many Requests" : "Service Unavailable",
            over_address ? "too many connections from this address\n" : "too many connections\n");
        (void)!::send(fd, a.data(), a.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      }
      ::close(fd);
      if (per_address_[ip] == 0) per_address_.erase(ip);
      continue;
    }
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    auto c = std::make_unique<Conn>();
    c->id = next_id_++;
    c->fd = fd;
    c->ip = ip;
    c->port = port;
    c->deadline = mono_s() + lim_.header_timeout_s;
    if (tls_) {
      c->ssl = SSL_new(tls_);
      SSL_set_fd(c->ssl, fd);
      SSL_set_accept_state(c->ssl);
    }
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.u64 = c->id;
    c->watching = EPOLLIN;
    ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &ev);
    ++per_address_[c->ip];
    conns_[c->id] = std::move(c);
  }
}

void HttpFront::answer(Conn& c, std::string text) {
  c.linger = c.state == Conn::kReading;
  c.state = Conn::kWriting;
  c.out = std::move(text);
  c.out_pos = 0;
  c.deadline = mono_s() + lim_.write_timeout_s;
  c.want_read = false;
  c.want_write = true;
  write_some(c);
}

void HttpFront::request_complete_or_not(Conn& c) {
  if (c.header_end == 0) {
    size_t end = c.in.find("\r\n\r\n");
    if (end != std::string::npos) {
      c.header_end = end + 4;
    } else if ((end = c.in.find("\n\n")) != std::string::npos) {
      c.header_end = end + 2;
    } else {
      if (c.in.size() > lim_.max_header_bytes)
        answer(c, plain_answer(431, "Request Header Fields Too Large",
                               "request headers over " + std::to_string(lim_.max_header_bytes) +
                                   " bytes\n"));
      return;
    }
    if (c.header_end > lim_.max_header_bytes)
      return answer(c, plain_answer(431, "Request Header Fields Too Large",
                                    "request headers over " +
                                        std::to_string(lim_.max_header_bytes) + " bytes\n"));
    // The body's length: Content-Length only (no chunked request bodies).
    long long length = 0;
    bool seen = false, expect = false;
    size_t p = c.in.find('\n');
    while (p != std::string::npos && p + 1 < c.header_end) {
      const size_t q = c.in.find('\n', p + 1);
      std::string line =
          lower(c.in.substr(p + 1, (q == std::string::npos ? c.header_end : q) - p - 1));
      p = q;
      if (line.rfind("expect:", 0) == 0 && line.find("100-continue") != std::string::npos)
        expect = true;
      if (line.rfind("transfer-encoding:", 0) == 0)
        return answer(
            c, plain_answer(411, "Length Required", "send the body with a Content-Length\n"));
      if (line.rfind("content-length:", 0) == 0) {
        char* endp = nullptr;
        const std::string v = line.substr(15);
        const long long n = std::strtoll(v.c_str(), &endp, 10);
        const bool digits = v.find_first_not_of(" \t\r0123456789") == std::string::npos;
        if (!digits || n < 0 || (seen && n != length))
          return answer(c, plain_answer(400, "Bad Request", "bad Content-Length\n"));
        length = n;
        seen = true;
      }
    }
    if (static_cast<unsigned long long>(length) > lim_.max_body_bytes)
      return answer(c, plain_answer(413, "Payload Too Large",
                                    "request bodies are at most " +
                                        std::to_string(lim_.max_body_bytes) + " bytes\n"));
    c.need = c.header_end + static_cast<size_t>(length);
    c.deadline = mono_s() + lim_.body_timeout_s;
    // A client that waits for "100 Continue" before its body (curl does for
    // large ones) gets it now, as the body is what we wait for. Best effort:
    // a client that misses it sends the body after its own timeout.
    if (expect && c.in.size() < c.need) {
      static const char kContinue[] = "HTTP/1.1 100 Continue\r\n\r\n";
      if (c.ssl)
        (void)SSL_write(c.ssl, kContinue, sizeof kContinue - 1);
      else
        (void)!::send(c.fd, kContinue, sizeof kContinue - 1, MSG_NOSIGNAL | MSG_DONTWAIT);
    }
  }
  if (c.in.size() < c.need) return;
  c.in.resize(c.need);  // one request per connection: anything after it is dropped
  c.state = Conn::kProcessing;
  watch(c);
  {
    std::lock_guard lock(mu_);
    if (work_.size() >= 1024) {
      c.state = Conn::kReading;
      return answer(c, plain_answer(503, "Service Unavailable", "ergd is overloaded\n"));
    }
    work_.push_back({c.id, c.in, c.fd, c.ip, c.port});
  }
  cv_.notify_one();
}

// A TLS read or write that returned n <= 0: either it waits for the socket
// (in whichever direction TLS asks, which can differ from the call's), or the
// connection is over.
void HttpFront::tls_blocked_or_closed(Conn& c, ssize_t n) {
  const int err = SSL_get_error(c.ssl, static_cast<int>(n));
  if (err == SSL_ERROR_WANT_READ || err == SSL_ERROR_WANT_WRITE) {
    c.want_read = err == SSL_ERROR_WANT_READ;
    c.want_write = err == SSL_ERROR_WANT_WRITE;
    return watch(c);
  }
  ERR_clear_error();
  close_conn(c.id);
}

void HttpFront::read_some(Conn& c) {
  char buf[16384];
  for (int round = 0; round < 64 && c.state == Conn::kReading; ++round) {
    ssize_t n;
    if (c.ssl) {
      n = SSL_read(c.ssl, buf, sizeof buf);
      if (n <= 0) return tls_blocked_or_closed(c, n);
    } else {
      n = ::recv(c.fd, buf, sizeof buf, 0);
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
        c.want_read = true;
        c.want_write = false;
        return watch(c);
      }
      if (n <= 0) return close_conn(c.id);
    }
    c.in.append(buf, static_cast<size_t>(n));
    const std::uint64_t id = c.id;
    request_complete_or_not(c);
    if (!conns_.count(id)) return;
  }
}

void HttpFront::write_some(Conn& c) {
  while (c.out_pos < c.out.size()) {
    const size_t left = c.out.size() - c.out_pos;
    ssize_t n;
    if (c.ssl) {
      n = SSL_write(c.ssl, c.out.data() + c.out_pos,
                    static_cast<int>(std::min<size_t>(left, 1 << 20)));
      if (n <= 0) return tls_blocked_or_closed(c, n);
    } else {
      n = ::send(c.fd, c.out.data() + c.out_pos, left, MSG_NOSIGNAL);
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
        c.want_read = false;
        c.want_write = true;
        return watch(c);
      }
      if (n <= 0) return close_conn(c.id);
    }
    c.out_pos += static_cast<size_t>(n);
  }
  // The whole answer is out. A client that was refused before it finished
  // sending may still be sending: closing with its bytes unread would reset
  // the connection, and it could lose the answer. Stop writing and read
  // (and drop) what it sends, until it closes or for 2 s at most.
  if (c.linger && !c.ssl && ::shutdown(c.fd, SHUT_WR) == 0) {
    c.state = Conn::kDraining;
    c.deadline = mono_s() + 2;
    c.want_read = true;
    c.want_write = false;
    return watch(c);
  }
  close_conn(c.id);
}

void HttpFront::drain(Conn& c) {
  char buf[16384];
  for (int round = 0; round < 64; ++round) {
    const ssize_t n = ::recv(c.fd, buf, sizeof buf, 0);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return;
    if (n <= 0) return close_conn(c.id);
  }
}

void HttpFront::on_event(Conn& c, std::uint32_t events) {
  if (c.state == Conn::kProcessing) return;
  if ((events & (EPOLLERR | EPOLLHUP)) && !(events & EPOLLIN)) return close_conn(c.id);
  if (c.state == Conn::kReading)
    read_some(c);
  else if (c.state == Conn::kDraining)
    drain(c);
  else
    write_some(c);
}

void HttpFront::expire(double now) {
  std::vector<std::uint64_t> late;
  for (const auto& [id, c] : conns_)
    if (c->state != Conn::kProcessing && now > c->deadline) late.push_back(id);
  // A late reader gets a 408 if it can take it at once; nobody waits for it.
  for (auto id : late) {
    Conn& c = *conns_.at(id);
    if (c.state == Conn::kReading && !c.ssl) {
      const std::string a = plain_answer(408, "Request Timeout", "request not complete in time\n");
      (void)!::send(c.fd, a.data(), a.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    }
    close_conn(id);
  }
}

void HttpFront::loop() {
  std::vector<epoll_event> events(256);
  double last_expire = 0;
  while (!stopping_) {
    const int n = ::epoll_wait(epoll_fd_, events.data(), static_cast<int>(events.size()), 100);
    for (int i = 0; i < n && !stopping_; ++i) {
      const std::uint64_t id = events[i].data.u64;
      if (id == kListenId) {
        on_accept();
      } else if (id == kWakeId) {
        std::uint64_t count;
        (void)!::read(wake_fd_, &count, sizeof count);
      } else if (auto it = conns_.find(id); it != conns_.end()) {
        on_event(*it->second, events[i].events);
      }
    }
    std::deque<Done> done;
    {
      std::lock_guard lock(mu_);
      done.swap(done_);
    }
    for (auto& d : done)
      if (auto it = conns_.find(d.id); it != conns_.end()) answer(*it->second, std::move(d.answer));
    const double now = mono_s();
    if (now - last_expire >= 0.1) {
      last_expire = now;
      expire(now);
    }
  }
}

}  // namespace erg::server
