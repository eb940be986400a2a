// SPDX-License-Identifier: Apache-2.0
#include "store/job_store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace erg::server {

namespace {

constexpr off_t kReserveBytes = 4 << 20;

// Whether the connection's last error was the disk being full.
bool is_full(sqlite3* db, int rc) {
  const int primary = rc & 0xff;
  if (primary == SQLITE_FULL) return true;
  const int err = sqlite3_system_errno(db);
  return (primary == SQLITE_IOERR || primary == SQLITE_CANTOPEN) &&
         (err == ENOSPC || err == EDQUOT);
}

[[noreturn]] void throw_store(sqlite3* db, int rc, const std::string& what) {
  const bool full = is_full(db, rc);
  std::string msg = std::string("sqlite: ") + sqlite3_errmsg(db) + what;
  if (full) msg += " (ENOSPC: the data directory's file system is full)";
  throw StoreError(msg, full);
}

std::int64_t now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// A prepared statement that finalizes itself.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) : db_(db) {
    const int rc = sqlite3_prepare_v2(db, sql, -1, &s_, nullptr);
    if (rc != SQLITE_OK) throw_store(db, rc, std::string(" in ") + sql);
  }
  ~Stmt() { sqlite3_finalize(s_); }
  Stmt& text(int i, const std::string& v) {
    sqlite3_bind_text(s_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& blob(int i, const std::string& v) {
    sqlite3_bind_blob(s_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& integer(int i, std::int64_t v) {
    sqlite3_bind_int64(s_, i, v);
    return *this;
  }
  Stmt& null(int i) {
    sqlite3_bind_null(s_, i);
    return *this;
  }
  // SQLITE_ROW or SQLITE_DONE; throws on errors other than a constraint.
  int step() {
    const int rc = sqlite3_step(s_);
    if (rc != SQLITE_ROW && rc != SQLITE_DONE && rc != SQLITE_CONSTRAINT) throw_store(db_, rc, "");
    return rc;
  }
  std::string column_blob(int i) {
    const void* p = sqlite3_column_blob(s_, i);
    return p ? std::string(static_cast<const char*>(p),
                           static_cast<size_t>(sqlite3_column_bytes(s_, i)))
             : std::string();
  }
  std::int64_t column_int(int i) { return sqlite3_column_int64(s_, i); }

 private:
  sqlite3* db_;
  sqlite3_stmt* s_ = nullptr;
};

template <class M>
M parse(const std::string& bytes) {
  M m;
  if (!m.ParseFromString(bytes)) throw std::runtime_error("job store: corrupt record");
  return m;
}

}  // namespace

JobStore::JobStore(const std::string& path, std::string reserve_path)
    : reserve_path_(std::move(reserve_path)) {
  if (sqlite3_open_v2(path.c_str(), &db_,
                      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX,
                      nullptr) != SQLITE_OK) {
    const std::string msg = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    throw std::runtime_error("cannot open job store " + path + ": " + msg);
  }
  sqlite3_busy_timeout(db_, 5000);
  // WAL + FULL: a committed transaction survives a crash of ergd or the OS.
  exec("PRAGMA journal_mode=WAL");
  exec("PRAGMA synchronous=FULL");
  exec(
      "CREATE TABLE IF NOT EXISTS jobs("
      " seq INTEGER PRIMARY KEY AUTOINCREMENT, id TEXT UNIQUE NOT NULL, tenant TEXT NOT NULL,"
      " state INTEGER NOT NULL, idem_key TEXT, job BLOB NOT NULL)");
  exec(
      "CREATE UNIQUE INDEX IF NOT EXISTS jobs_idem ON jobs(tenant, idem_key)"
      " WHERE idem_key IS NOT NULL");
  exec("CREATE INDEX IF NOT EXISTS jobs_tenant ON jobs(tenant, seq)");
  exec("CREATE INDEX IF NOT EXISTS jobs_state ON jobs(state, seq)");
  exec(
      "CREATE TABLE IF NOT EXISTS events("
      " id INTEGER PRIMARY KEY AUTOINCREMENT, job_id TEXT NOT NULL, event BLOB NOT NULL)");
  exec("CREATE INDEX IF NOT EXISTS events_job ON events(job_id, id)");
  restore_reserve();
}

bool JobStore::restore_reserve() {
  if (reserve_path_.empty()) return false;
  struct stat st {};
  if (::stat(reserve_path_.c_str(), &st) == 0 && st.st_size >= kReserveBytes) return true;
  const int fd = ::open(reserve_path_.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0) return false;
  // posix_fallocate really allocates the blocks (ftruncate would make a
  // sparse file that frees nothing when deleted).
  const int err = ::posix_fallocate(fd, 0, kReserveBytes);
  ::close(fd);
  if (err != 0) {
    ::unlink(reserve_path_.c_str());  // no half reserve: it would only take space
    return false;
  }
  return true;
}

bool JobStore::release_reserve() {
  return !reserve_path_.empty() && ::unlink(reserve_path_.c_str()) == 0;
}

template <class F>
auto JobStore::write(F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const StoreError& e) {
    if (!e.full() || !release_reserve()) throw;
    std::fprintf(stderr, "ergd: the data directory is full: released the %lld-byte reserve %s\n",
                 static_cast<long long>(kReserveBytes), reserve_path_.c_str());
    return f();
  }
}

JobStore::~JobStore() {
  sqlite3_close(db_);
}

void JobStore::exec(const char* sql) {
  char* err = nullptr;
  const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, &err);
  if (rc != SQLITE_OK) {
    sqlite3_free(err);
    throw_store(db_, rc, std::string(" in ") + sql);
  }
}

std::pair<erg::v1::Job, bool> JobStore::insert(const erg::v1::Job& job) {
  std::lock_guard lock(mu_);
  return write([&]() -> std::pair<erg::v1::Job, bool> {
    Stmt s(db_, "INSERT INTO jobs(id, tenant, state, idem_key, job) VALUES(?,?,?,?,?)");
    s.text(1, job.id()).text(2, job.tenant()).integer(3, job.state());
    if (job.idempotency_key().empty())
      s.null(4);
    else
      s.text(4, job.idempotency_key());
    s.blob(5, job.SerializeAsString());
    if (s.step() == SQLITE_DONE) return {job, true};
    // The key is taken: the job it created.
    Stmt q(db_, "SELECT job FROM jobs WHERE tenant = ? AND idem_key = ?");
    q.text(1, job.tenant()).text(2, job.idempotency_key());
    if (q.step() != SQLITE_ROW) throw std::runtime_error("job store: insert failed");
    return {parse<erg::v1::Job>(q.column_blob(0)), false};
  });
}

void JobStore::update(const erg::v1::Job& job) {
  std::lock_guard lock(mu_);
  write([&] {
    Stmt s(db_, "UPDATE jobs SET state = ?, job = ? WHERE id = ?");
    s.integer(1, job.state()).blob(2, job.SerializeAsString()).text(3, job.id()).step();
  });
}

std::optional<erg::v1::Job> JobStore::get(const std::string& id) {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT job FROM jobs WHERE id = ?");
  s.text(1, id);
  if (s.step() != SQLITE_ROW) return std::nullopt;
  return parse<erg::v1::Job>(s.column_blob(0));
}

std::vector<erg::v1::Job> JobStore::list(const std::string& tenant, int state,
                                         std::int64_t before_seq, int limit,
                                         std::int64_t* last_seq) {
  std::lock_guard lock(mu_);
  Stmt s(db_,
         "SELECT job, seq FROM jobs WHERE tenant = ? AND (? = 0 OR state = ?) AND seq < ?"
         " ORDER BY seq DESC LIMIT ?");
  s.text(1, tenant).integer(2, state).integer(3, state);
  s.integer(4, before_seq > 0 ? before_seq : INT64_MAX).integer(5, limit);
  std::vector<erg::v1::Job> out;
  *last_seq = 0;
  while (s.step() == SQLITE_ROW) {
    out.push_back(parse<erg::v1::Job>(s.column_blob(0)));
    *last_seq = s.column_int(1);
  }
  return out;
}

std::vector<erg::v1::Job> JobStore::in_states(const std::vector<int>& states) {
  std::lock_guard lock(mu_);
  std::vector<erg::v1::Job> out;
  std::string sql = "SELECT job FROM jobs WHERE state IN (";
  for (size_t i = 0; i < states.size(); ++i) sql += (i ? ",?" : "?");
  sql += ") ORDER BY seq ASC";
  Stmt s(db_, sql.c_str());
  for (size_t i = 0; i < states.size(); ++i) s.integer(static_cast<int>(i) + 1, states[i]);
  while (s.step() == SQLITE_ROW) out.push_back(parse<erg::v1::Job>(s.column_blob(0)));
  return out;
}

std::optional<erg::v1::Job> JobStore::by_key(const std::string& tenant, const std::string& key) {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT job FROM jobs WHERE tenant = ? AND idem_key = ?");
  s.text(1, tenant).text(2, key);
  if (s.step() != SQLITE_ROW) return std::nullopt;
  return parse<erg::v1::Job>(s.column_blob(0));
}

std::int64_t JobStore::seq_of(const std::string& id) {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT seq FROM jobs WHERE id = ?");
  s.text(1, id);
  return s.step() == SQLITE_ROW ? s.column_int(0) : 0;
}

std::vector<std::pair<int, std::int64_t>> JobStore::count_by_state() {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT state, COUNT(*) FROM jobs GROUP BY state");
  std::vector<std::pair<int, std::int64_t>> out;
  while (s.step() == SQLITE_ROW)
    out.emplace_back(static_cast<int>(s.column_int(0)), s.column_int(1));
  return out;
}

erg::v1::JobEvent JobStore::append_event(const std::string& job_id, erg::v1::JobEvent ev) {
  {
    std::lock_guard lock(mu_);
    ev.set_unix_ms(now_ms());
    ev.clear_id();
    write([&] {
      Stmt s(db_, "INSERT INTO events(job_id, event) VALUES(?, ?)");
      s.text(1, job_id).blob(2, ev.SerializeAsString()).step();
    });
    ev.set_id(sqlite3_last_insert_rowid(db_));
    ++generation_;
  }
  cv_.notify_all();
  return ev;
}

std::vector<erg::v1::JobEvent> JobStore::events_after(const std::string& job_id, std::int64_t after,
                                                      int limit) {
  std::lock_guard lock(mu_);
  Stmt s(db_, "SELECT id, event FROM events WHERE job_id = ? AND id > ? ORDER BY id LIMIT ?");
  s.text(1, job_id).integer(2, after).integer(3, limit);
  std::vector<erg::v1::JobEvent> out;
  while (s.step() == SQLITE_ROW) {
    auto ev = parse<erg::v1::JobEvent>(s.column_blob(1));
    ev.set_id(s.column_int(0));
    out.push_back(std::move(ev));
  }
  return out;
}

std::uint64_t JobStore::wait_events(std::uint64_t seen, int timeout_ms) {
  std::unique_lock lock(mu_);
  cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] { return generation_ != seen; });
  return generation_;
}

std::uint64_t JobStore::generation() {
  std::lock_guard lock(mu_);
  return generation_;
}

}  // namespace erg::server
