#pragma once
/// \file
/// ReportStore: the service's persistent records in one SQLite file (DATA_DIR/gd.sqlite): jobs
/// (status, progress at the end, the summary JSON and the names of their report files, which live
/// under DATA_DIR/jobs/<job_id>/) and uploaded meshes (their OBJ files live under
/// DATA_DIR/meshes/). WAL journal with synchronous=FULL: a committed row survives a kill -9 (and
/// a power loss) at any moment; a job's report and its final status are committed in one
/// transaction. The schema is versioned with PRAGMA user_version (kSchemaVersion).
/// All methods are thread-safe (one connection behind a mutex) and return a Status.

#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "service/status.h"

struct sqlite3;

namespace gd::service {

/// A job's status; the values are those of the proto's JobStatus.
enum class JobState { kQueued = 1, kRunning = 2, kSucceeded = 3, kFailed = 4, kInterrupted = 5, kCancelled = 6 };

/// "queued", "running", "succeeded", "failed", "interrupted", "cancelled".
const char* job_state_name(JobState s);
/// True for succeeded, failed, interrupted and cancelled.
inline bool job_finished(JobState s) {
  return s == JobState::kSucceeded || s == JobState::kFailed || s == JobState::kInterrupted ||
         s == JobState::kCancelled;
}

/// One job as listed.
struct JobRecord {
  std::string job_id;
  JobState status = JobState::kQueued;
  double progress = 0;     ///< 0..1
  double sim_time = 0;     ///< s
  double end_time = 0;     ///< s
  std::string message;     ///< failure reason, if any
  std::string garment, material, task, label;
  std::string created_at;  ///< ISO 8601 UTC
  std::string finished_at;
  std::string request_json;  ///< the submitted request (for reference)
  /// The principal of the token that submitted the job (TokenSet, auth.h); "" without tokens.
  std::string owner;
};

/// Whether a caller (a principal, "" on a server without tokens) may see a job of `owner`: its
/// own jobs, jobs stored before tokens were used (owner ""), and every job when it runs without
/// tokens.
inline bool job_visible(const std::string& owner, const std::string& caller) {
  return caller.empty() || owner.empty() || owner == caller;
}

/// A job with its report.
struct StoredReport {
  JobRecord job;
  std::string summary_json;        ///< empty until the job completes
  std::vector<std::string> files;  ///< report file names relative to the job's directory
};

/// An uploaded mesh.
struct MeshRecord {
  std::string mesh_id;
  std::string name;
  std::string path;   ///< the OBJ file
  int vertices = 0;
  int triangles = 0;
  std::string created_at;
  std::string content_hash;  ///< of its name and OBJ text (an identical upload returns this mesh)
  double last_used = 0;      ///< Unix time of its upload or last use (the mesh lease)
  std::string expired_at;    ///< set when the lease deleted its file ('' while it is live)
};

/// The current time, ISO 8601 UTC with seconds ("2026-01-31T12:00:00Z").
std::string now_iso8601();
/// A new id unique across restarts and unguessable: prefix + UTC timestamp + 128 random bits
/// ("j-20260131T120000-" and 32 hex digits).
std::string new_id(const std::string& prefix);

class ReportStore {
 public:
  static constexpr int kSchemaVersion = 3;  ///< 2: jobs.owner; 3: meshes' hash, use and expiry

  /// Opens (creating if needed) the database at `path`. Throws sim::InputError when it cannot be
  /// opened or was written by a newer schema.
  explicit ReportStore(const std::string& path);
  ~ReportStore();
  ReportStore(const ReportStore&) = delete;
  ReportStore& operator=(const ReportStore&) = delete;

  const std::string& path() const { return path_; }

  /// Adds a job (normally queued).
  Status insert_job(const JobRecord& job);
  /// Sets a job's status (and message); finished states also set finished_at.
  Status set_status(const std::string& job_id, JobState status, const std::string& message = "");
  /// Stores a finished job: its final record, summary and file names, in one transaction.
  Status complete(const JobRecord& job, const std::string& summary_json, const std::vector<std::string>& files);
  /// Marks every queued or running job interrupted (at startup: a previous process died before or
  /// while they ran), running ones with `running_message`, queued ones with `queued_message`; their
  /// ids into `ids` when given. Returns how many were marked, or -1 on error.
  int interrupt_unfinished(const std::string& running_message, const std::string& queued_message,
                           std::vector<std::string>* ids = nullptr);
  /// The job and its report; NOT_FOUND for an unknown id.
  Status get(const std::string& job_id, StoredReport* out);
  /// Jobs `caller` may see (job_visible) newest first, and their total count.
  Status list(int limit, int offset, std::vector<JobRecord>* out, int* total, const std::string& caller = {});

  Status insert_mesh(const MeshRecord& mesh);
  /// NOT_FOUND for an unknown id; an expired mesh comes back with expired_at set.
  Status get_mesh(const std::string& mesh_id, MeshRecord* out);
  /// The live meshes.
  Status list_meshes(std::vector<MeshRecord>* out);
  /// A live mesh with this content hash, if any (*found false otherwise).
  Status find_mesh_by_hash(const std::string& hash, MeshRecord* out, bool* found);
  /// Sets a mesh's last use (Unix time).
  Status touch_mesh(const std::string& mesh_id, double when);
  /// The live meshes last used before `before` (Unix time).
  Status idle_meshes(double before, std::vector<MeshRecord>* out);
  /// Marks a mesh expired (its file is gone); get_mesh still finds it, list_meshes no longer.
  Status expire_mesh(const std::string& mesh_id);

 private:
  Status exec(const char* sql);
  Status error(const std::string& what);

  std::string path_;
  std::mutex mu_;
  sqlite3* db_ = nullptr;
};

}  // namespace gd::service
