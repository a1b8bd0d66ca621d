#include "service/report_store.h"

#include <spdlog/fmt/fmt.h>
#include <sqlite3.h>

#include <ctime>

#include "service/auth.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::service {

const char* job_state_name(JobState s) {
  switch (s) {
    case JobState::kQueued: return "queued";
    case JobState::kRunning: return "running";
    case JobState::kSucceeded: return "succeeded";
    case JobState::kFailed: return "failed";
    case JobState::kInterrupted: return "interrupted";
    case JobState::kCancelled: return "cancelled";
  }
  return "unknown";
}

std::string now_iso8601() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string new_id(const std::string& prefix) {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y%m%dT%H%M%S", &tm);
  return fmt::format("{}{}-{}", prefix, buf, random_hex(16));
}

namespace {

/// A prepared statement, finalised on scope exit.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) : db_(db) { rc_ = sqlite3_prepare_v2(db, sql, -1, &st_, nullptr); }
  ~Stmt() { sqlite3_finalize(st_); }
  bool ok() const { return rc_ == SQLITE_OK; }
  Stmt& bind(int i, const std::string& s) {
    sqlite3_bind_text(st_, i, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& bind(int i, double v) {
    sqlite3_bind_double(st_, i, v);
    return *this;
  }
  Stmt& bind(int i, int64_t v) {
    sqlite3_bind_int64(st_, i, v);
    return *this;
  }
  Stmt& bind(int i, int v) { return bind(i, static_cast<int64_t>(v)); }
  /// SQLITE_ROW, SQLITE_DONE or an error code.
  int step() { return sqlite3_step(st_); }
  std::string text(int c) const {
    const unsigned char* p = sqlite3_column_text(st_, c);
    return p ? std::string(reinterpret_cast<const char*>(p), sqlite3_column_bytes(st_, c)) : std::string();
  }
  double real(int c) const { return sqlite3_column_double(st_, c); }
  int64_t integer(int c) const { return sqlite3_column_int64(st_, c); }

 private:
  sqlite3* db_;
  sqlite3_stmt* st_ = nullptr;
  int rc_ = SQLITE_ERROR;
};

constexpr const char* kJobColumns =
    "job_id, status, progress, sim_time, end_time, message, garment, material, task, label, created_at, "
    "finished_at, request_json, owner";

JobRecord read_job(const Stmt& s) {
  JobRecord j;
  j.job_id = s.text(0);
  j.status = static_cast<JobState>(s.integer(1));
  j.progress = s.real(2);
  j.sim_time = s.real(3);
  j.end_time = s.real(4);
  j.message = s.text(5);
  j.garment = s.text(6);
  j.material = s.text(7);
  j.task = s.text(8);
  j.label = s.text(9);
  j.created_at = s.text(10);
  j.finished_at = s.text(11);
  j.request_json = s.text(12);
  j.owner = s.text(13);
  return j;
}

}  // namespace

ReportStore::ReportStore(const std::string& path) : path_(path) {
  if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX,
                      nullptr) != SQLITE_OK) {
    const std::string msg = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    throw sim::InputError(fmt::format("cannot open the database '{}': {} (check --data-dir)", path, msg));
  }
  sqlite3_busy_timeout(db_, 5000);
  auto must = [&](const char* sql) {
    if (Status st = exec(sql); !st.ok()) {
      sqlite3_close(db_);
      db_ = nullptr;
      throw sim::InputError(fmt::format("database '{}': {}", path, st.message()));
    }
  };
  must("PRAGMA journal_mode=WAL");
  must("PRAGMA synchronous=FULL");
  must("PRAGMA foreign_keys=ON");
  int version = 0;
  {
    Stmt s(db_, "PRAGMA user_version");
    if (s.ok() && s.step() == SQLITE_ROW) version = static_cast<int>(s.integer(0));
  }
  if (version > kSchemaVersion) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw sim::InputError(fmt::format("database '{}' has schema version {}, newer than this server's {}; use a newer "
                                      "gd-server or another --data-dir",
                                      path, version, kSchemaVersion));
  }
  if (version < 1) {
    must("BEGIN IMMEDIATE");
    must(R"sql(
      CREATE TABLE IF NOT EXISTS jobs(
        seq INTEGER PRIMARY KEY AUTOINCREMENT,
        job_id TEXT UNIQUE NOT NULL,
        status INTEGER NOT NULL,
        progress REAL NOT NULL DEFAULT 0,
        sim_time REAL NOT NULL DEFAULT 0,
        end_time REAL NOT NULL DEFAULT 0,
        message TEXT NOT NULL DEFAULT '',
        garment TEXT NOT NULL DEFAULT '',
        material TEXT NOT NULL DEFAULT '',
        task TEXT NOT NULL DEFAULT '',
        label TEXT NOT NULL DEFAULT '',
        created_at TEXT NOT NULL DEFAULT '',
        finished_at TEXT NOT NULL DEFAULT '',
        request_json TEXT NOT NULL DEFAULT '',
        summary_json TEXT NOT NULL DEFAULT '');
      CREATE TABLE IF NOT EXISTS report_files(
        job_id TEXT NOT NULL REFERENCES jobs(job_id),
        name TEXT NOT NULL,
        PRIMARY KEY(job_id, name));
      CREATE TABLE IF NOT EXISTS meshes(
        mesh_id TEXT PRIMARY KEY,
        name TEXT NOT NULL,
        path TEXT NOT NULL,
        vertices INTEGER NOT NULL,
        triangles INTEGER NOT NULL,
        created_at TEXT NOT NULL);
      PRAGMA user_version = 1;
    )sql");
    must("COMMIT");
    version = 1;
  }
  if (version < 2) {  // jobs.owner: the principal of the token that submitted the job ('' without tokens)
    must("BEGIN IMMEDIATE");
    must("ALTER TABLE jobs ADD COLUMN owner TEXT NOT NULL DEFAULT ''; PRAGMA user_version = 2;");
    must("COMMIT");
  }
  if (version < 3) {  // meshes: content hash (identical uploads), last use and expiry (the mesh lease)
    must("BEGIN IMMEDIATE");
    must("ALTER TABLE meshes ADD COLUMN content_hash TEXT NOT NULL DEFAULT ''; "
         "ALTER TABLE meshes ADD COLUMN last_used REAL NOT NULL DEFAULT 0; "
         "ALTER TABLE meshes ADD COLUMN expired_at TEXT NOT NULL DEFAULT ''; "
         "UPDATE meshes SET last_used = CAST(strftime('%s', 'now') AS REAL); "  // the lease starts now
         "PRAGMA user_version = 3;");
    must("COMMIT");
  }
}

ReportStore::~ReportStore() {
  if (db_) sqlite3_close(db_);
}

Status ReportStore::error(const std::string& what) {
  return Status::Internal(fmt::format("database '{}': {}: {}", path_, what, sqlite3_errmsg(db_)));
}

Status ReportStore::exec(const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    Status st = Status::Internal(err ? err : "unknown error");
    sqlite3_free(err);
    return st;
  }
  return Status::Ok();
}

Status ReportStore::insert_job(const JobRecord& j) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt s(db_,
         "INSERT INTO jobs(job_id, status, progress, sim_time, end_time, message, garment, material, task, label, "
         "created_at, finished_at, request_json, owner) VALUES(?,?,?,?,?,?,?,?,?,?,?,?,?,?)");
  if (!s.ok()) return error("prepare insert job");
  s.bind(1, j.job_id).bind(2, static_cast<int>(j.status)).bind(3, j.progress).bind(4, j.sim_time).bind(5, j.end_time);
  s.bind(6, j.message).bind(7, j.garment).bind(8, j.material).bind(9, j.task).bind(10, j.label);
  s.bind(11, j.created_at).bind(12, j.finished_at).bind(13, j.request_json).bind(14, j.owner);
  if (s.step() != SQLITE_DONE) return error("insert job " + j.job_id);
  return Status::Ok();
}

Status ReportStore::set_status(const std::string& job_id, JobState status, const std::string& message) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt s(db_, "UPDATE jobs SET status = ?, message = ?, finished_at = ? WHERE job_id = ?");
  if (!s.ok()) return error("prepare set status");
  s.bind(1, static_cast<int>(status)).bind(2, message).bind(3, job_finished(status) ? now_iso8601() : std::string());
  s.bind(4, job_id);
  if (s.step() != SQLITE_DONE) return error("set status of " + job_id);
  if (sqlite3_changes(db_) == 0) return Status::NotFound(fmt::format("no job '{}'", job_id));
  return Status::Ok();
}

Status ReportStore::complete(const JobRecord& j, const std::string& summary_json, const std::vector<std::string>& files) {
  std::lock_guard<std::mutex> lock(mu_);
  if (Status st = exec("BEGIN IMMEDIATE"); !st.ok()) return error("begin");
  auto fail = [&](const std::string& what) {
    Status st = error(what);
    exec("ROLLBACK");
    return st;
  };
  {
    Stmt s(db_,
           "UPDATE jobs SET status = ?, progress = ?, sim_time = ?, end_time = ?, message = ?, finished_at = ?, "
           "summary_json = ? WHERE job_id = ?");
    if (!s.ok()) return fail("prepare complete");
    s.bind(1, static_cast<int>(j.status)).bind(2, j.progress).bind(3, j.sim_time).bind(4, j.end_time);
    s.bind(5, j.message).bind(6, j.finished_at).bind(7, summary_json).bind(8, j.job_id);
    if (s.step() != SQLITE_DONE) return fail("complete " + j.job_id);
    if (sqlite3_changes(db_) == 0) {
      exec("ROLLBACK");
      return Status::NotFound(fmt::format("no job '{}'", j.job_id));
    }
  }
  for (const std::string& f : files) {
    Stmt s(db_, "INSERT OR REPLACE INTO report_files(job_id, name) VALUES(?, ?)");
    if (!s.ok()) return fail("prepare file");
    s.bind(1, j.job_id).bind(2, f);
    if (s.step() != SQLITE_DONE) return fail("file " + f);
  }
  if (Status st = exec("COMMIT"); !st.ok()) return fail("commit");
  return Status::Ok();
}

int ReportStore::interrupt_unfinished(const std::string& running_message, const std::string& queued_message,
                                      std::vector<std::string>* ids) {
  std::lock_guard<std::mutex> lock(mu_);
  const int queued = static_cast<int>(JobState::kQueued), running = static_cast<int>(JobState::kRunning);
  if (ids) {
    ids->clear();
    Stmt q(db_, "SELECT job_id FROM jobs WHERE status IN (?, ?) ORDER BY job_id");
    if (!q.ok()) return -1;
    q.bind(1, queued).bind(2, running);
    while (q.step() == SQLITE_ROW) ids->push_back(q.text(0));
  }
  Stmt s(db_, "UPDATE jobs SET message = CASE status WHEN ? THEN ? ELSE ? END, status = ?, finished_at = ? "
              "WHERE status IN (?, ?)");
  if (!s.ok()) return -1;
  s.bind(1, running).bind(2, running_message).bind(3, queued_message);
  s.bind(4, static_cast<int>(JobState::kInterrupted)).bind(5, now_iso8601());
  s.bind(6, queued).bind(7, running);
  if (s.step() != SQLITE_DONE) return -1;
  return sqlite3_changes(db_);
}

Status ReportStore::get(const std::string& job_id, StoredReport* out) {
  std::lock_guard<std::mutex> lock(mu_);
  {
    Stmt s(db_, fmt::format("SELECT {}, summary_json FROM jobs WHERE job_id = ?", kJobColumns).c_str());
    if (!s.ok()) return error("prepare get");
    s.bind(1, job_id);
    const int rc = s.step();
    if (rc == SQLITE_DONE) return Status::NotFound(fmt::format("no job '{}' on this server; ListReports lists the jobs", job_id));
    if (rc != SQLITE_ROW) return error("get " + job_id);
    out->job = read_job(s);
    out->summary_json = s.text(14);
  }
  Stmt f(db_, "SELECT name FROM report_files WHERE job_id = ? ORDER BY name");
  if (!f.ok()) return error("prepare files");
  f.bind(1, job_id);
  out->files.clear();
  int rc;
  while ((rc = f.step()) == SQLITE_ROW) out->files.push_back(f.text(0));
  if (rc != SQLITE_DONE) return error("files of " + job_id);
  return Status::Ok();
}

Status ReportStore::list(int limit, int offset, std::vector<JobRecord>* out, int* total, const std::string& owner) {
  std::lock_guard<std::mutex> lock(mu_);
  constexpr const char* kVisible = "(?1 = '' OR owner = '' OR owner = ?1)";  // job_visible() in SQL
  {
    Stmt c(db_, fmt::format("SELECT COUNT(*) FROM jobs WHERE {}", kVisible).c_str());
    if (!c.ok()) return error("prepare count");
    c.bind(1, owner);
    if (c.step() != SQLITE_ROW) return error("count jobs");
    *total = static_cast<int>(c.integer(0));
  }
  Stmt s(db_, fmt::format("SELECT {} FROM jobs WHERE {} ORDER BY seq DESC LIMIT ?2 OFFSET ?3", kJobColumns, kVisible)
                  .c_str());
  if (!s.ok()) return error("prepare list");
  s.bind(1, owner).bind(2, limit).bind(3, offset);
  out->clear();
  int rc;
  while ((rc = s.step()) == SQLITE_ROW) out->push_back(read_job(s));
  if (rc != SQLITE_DONE) return error("list jobs");
  return Status::Ok();
}

Status ReportStore::insert_mesh(const MeshRecord& m) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt s(db_,
         "INSERT INTO meshes(mesh_id, name, path, vertices, triangles, created_at, content_hash, last_used) "
         "VALUES(?,?,?,?,?,?,?,?)");
  if (!s.ok()) return error("prepare insert mesh");
  s.bind(1, m.mesh_id).bind(2, m.name).bind(3, m.path).bind(4, m.vertices).bind(5, m.triangles).bind(6, m.created_at);
  s.bind(7, m.content_hash).bind(8, m.last_used);
  if (s.step() != SQLITE_DONE) return error("insert mesh " + m.mesh_id);
  return Status::Ok();
}

namespace {

constexpr const char* kMeshColumns =
    "mesh_id, name, path, vertices, triangles, created_at, content_hash, last_used, expired_at";

MeshRecord read_mesh(const Stmt& s) {
  MeshRecord m;
  m.mesh_id = s.text(0);
  m.name = s.text(1);
  m.path = s.text(2);
  m.vertices = static_cast<int>(s.integer(3));
  m.triangles = static_cast<int>(s.integer(4));
  m.created_at = s.text(5);
  m.content_hash = s.text(6);
  m.last_used = s.real(7);
  m.expired_at = s.text(8);
  return m;
}

}  // namespace

Status ReportStore::get_mesh(const std::string& mesh_id, MeshRecord* out) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt s(db_, fmt::format("SELECT {} FROM meshes WHERE mesh_id = ?", kMeshColumns).c_str());
  if (!s.ok()) return error("prepare get mesh");
  s.bind(1, mesh_id);
  const int rc = s.step();
  if (rc == SQLITE_DONE)
    return Status::NotFound(fmt::format("no mesh '{}' on this server; upload it with UploadMesh (ListGarments lists them)", mesh_id));
  if (rc != SQLITE_ROW) return error("get mesh " + mesh_id);
  *out = read_mesh(s);
  return Status::Ok();
}

Status ReportStore::list_meshes(std::vector<MeshRecord>* out) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt s(db_, fmt::format("SELECT {} FROM meshes WHERE expired_at = '' ORDER BY created_at, mesh_id", kMeshColumns)
                  .c_str());
  if (!s.ok()) return error("prepare list meshes");
  out->clear();
  int rc;
  while ((rc = s.step()) == SQLITE_ROW) out->push_back(read_mesh(s));
  if (rc != SQLITE_DONE) return error("list meshes");
  return Status::Ok();
}

Status ReportStore::find_mesh_by_hash(const std::string& hash, MeshRecord* out, bool* found) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt s(db_, fmt::format("SELECT {} FROM meshes WHERE content_hash = ? AND expired_at = '' ORDER BY created_at "
                          "LIMIT 1", kMeshColumns).c_str());
  if (!s.ok()) return error("prepare find mesh");
  s.bind(1, hash);
  const int rc = s.step();
  *found = rc == SQLITE_ROW;
  if (rc != SQLITE_ROW && rc != SQLITE_DONE) return error("find mesh");
  if (*found) *out = read_mesh(s);
  return Status::Ok();
}

Status ReportStore::touch_mesh(const std::string& mesh_id, double when) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt s(db_, "UPDATE meshes SET last_used = ? WHERE mesh_id = ?");
  if (!s.ok()) return error("prepare touch mesh");
  s.bind(1, when).bind(2, mesh_id);
  if (s.step() != SQLITE_DONE) return error("touch mesh " + mesh_id);
  return Status::Ok();
}

Status ReportStore::idle_meshes(double before, std::vector<MeshRecord>* out) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt s(db_, fmt::format("SELECT {} FROM meshes WHERE expired_at = '' AND last_used < ? ORDER BY last_used",
                          kMeshColumns).c_str());
  if (!s.ok()) return error("prepare idle meshes");
  s.bind(1, before);
  out->clear();
  int rc;
  while ((rc = s.step()) == SQLITE_ROW) out->push_back(read_mesh(s));
  if (rc != SQLITE_DONE) return error("idle meshes");
  return Status::Ok();
}

Status ReportStore::expire_mesh(const std::string& mesh_id) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt s(db_, "UPDATE meshes SET expired_at = ? WHERE mesh_id = ?");
  if (!s.ok()) return error("prepare expire mesh");
  s.bind(1, now_iso8601()).bind(2, mesh_id);
  if (s.step() != SQLITE_DONE) return error("expire mesh " + mesh_id);
  return Status::Ok();
}

}  // namespace gd::service
