#include "tools/fleet/fleet_team.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <limits>

#include "runtime_common/traffic_stats.h"

namespace ccm::fleet {
namespace {

using Clock = std::chrono::steady_clock;
constexpr AgentId kLeftOutIds = 60000;

struct Traffic {
  uint64_t up_bytes = 0, down_bytes = 0;
};

Traffic SumTraffic(const std::vector<rt::TopicCountersSnapshot>& topics) {
  Traffic t;
  for (const auto& c : topics) (c.direction == "out" ? t.up_bytes : t.down_bytes) += c.payload_bytes;
  return t;
}

}  // namespace

std::unique_ptr<Team> Team::Load(const TeamOptions& options, std::string* error) {
  std::unique_ptr<Team> team(new Team(options));
  AgentId next_id = 1;
  std::vector<std::pair<double, AgentBatch>> timed;  // keep_batches: (start time [s], batch)
  for (size_t r = 0; r < options.recordings.size(); ++r) {
    auto rec = replay::LoadRecording(options.recordings[r], error);
    if (!rec) return nullptr;
    std::map<AgentId, AgentId> to;
    std::map<AgentId, size_t> member_of;
    int64_t t0 = std::numeric_limits<int64_t>::max();
    for (const AgentBatch& b : rec->batches) t0 = std::min(t0, b.stamp_ns);
    for (replay::RecordedAgent& a : rec->agents) {
      if (options.max_agents > 0 && team->members_.size() >= options.max_agents) break;
      if (next_id >= kLeftOutIds) return *error = "more than " + std::to_string(kLeftOutIds - 1) + " agents", nullptr;
      to[a.id] = next_id;
      Member m;
      m.id = next_id++;
      m.name = options.recordings.size() > 1 ? "t" + std::to_string(r + 1) + "_" + a.name : a.name;
      m.recording = r;
      m.stagger_s = options.stagger_s * static_cast<double>(r);
      m.t0_ns = t0;
      member_of[a.id] = team->members_.size();
      team->members_.push_back(std::move(m));
      replay::RecordedAgent renamed = a;
      renamed.id = to[a.id];
      renamed.name = team->members_.back().name;
      team->merged_.agents.push_back(std::move(renamed));
    }
    // Links to agents left out (--agents) are renamed too, into ids no member has: two copies
    // of one recording must never refer to each other's objects.
    for (const replay::RecordedAgent& a : rec->agents) {
      if (!to.count(a.id)) to[a.id] = static_cast<AgentId>(kLeftOutIds + (r * 100 + a.id) % 5000);
    }
    for (AgentBatch& b : rec->batches) {
      const auto m = member_of.find(b.agent);
      if (m == member_of.end()) continue;
      agent::RemapAgents(to, &b);
      if (options.keep_batches) timed.emplace_back(options.stagger_s * r + (b.stamp_ns - t0) * 1e-9, b);
      team->members_[m->second].batches.push_back(std::move(b));
    }
  }
  if (team->members_.empty()) return *error = "the recordings hold no agents", nullptr;
  std::stable_sort(timed.begin(), timed.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  for (auto& [t, b] : timed) team->merged_.batches.push_back(std::move(b));
  return team;
}

Team::~Team() {
  for (Member& m : members_) {
    if (m.comm) m.comm->Stop();
  }
}

double Team::duration_s() const {
  double longest = 0.0;
  for (const Member& m : members_) {
    const double recorded = m.source ? m.source->duration_s()
                            : m.batches.empty()
                                ? 0.0
                                : static_cast<double>(m.batches.back().stamp_ns - m.t0_ns) * 1e-9;
    longest = std::max(longest, recorded + m.stagger_s);
  }
  return longest / options_.speed;
}

bool Team::Connect(const agent::AgentConfig& config, const rt::SessionOptions& session, Clock::time_point start,
                   std::string* error) {
  started_ = start;
  for (Member& m : members_) {
    agent::AgentConfig c = config;
    c.agent_id = m.id;
    const auto begin = start + std::chrono::duration_cast<Clock::duration>(
                                   std::chrono::duration<double>(m.stagger_s / options_.speed));
    m.source = std::make_unique<agent::RecordedDataSource>(std::move(m.batches), m.t0_ns, begin, options_.speed);
    m.batches.clear();
    m.acks = std::make_unique<agent::AckTracker>(std::chrono::milliseconds(static_cast<int>(c.resend_holdoff_s * 1000)));
    m.comm = agent::AgentComm::Create(c, session, m.source.get(), m.acks.get(), error);
    if (!m.comm) {
      *error = "agent " + std::to_string(m.id) + ": " + *error;
      return false;
    }
    m.comm->Start();
  }
  return true;
}

bool Team::Finished() const {
  return std::all_of(members_.begin(), members_.end(), [](const Member& m) { return !m.source || m.source->finished(); });
}

bool Team::Drain(std::chrono::milliseconds timeout) {
  const auto played = Clock::now();
  const auto deadline = played + timeout;
  bool all = true;
  for (Member& m : members_) {
    if (!m.comm) continue;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    all = m.comm->WaitDrained(std::max(left, std::chrono::milliseconds(0))) && all;
  }
  drain_s_ = std::chrono::duration<double>(Clock::now() - played).count();
  for (Member& m : members_) {
    if (m.comm) m.comm->Stop();
  }
  return all;
}

Team::Totals Team::Sum() const {
  Totals t;
  for (const Member& m : members_) {
    if (!m.comm) continue;
    const agent::AgentCommStats s = m.comm->Stats();
    const Traffic traffic = SumTraffic(m.comm->Traffic());
    t.sent += s.kfs_sent;
    t.acked += s.kfs_acked;
    t.unacked += s.kfs_unacked;
    t.resent += s.kfs_resent;
    t.shared += s.server_keyframes_received;
    t.up += traffic.up_bytes;
    t.down += traffic.down_bytes;
    t.matched += m.comm->matched_servers() > 0 ? 1 : 0;
    t.ack_p95_max = std::max(t.ack_p95_max, s.ack_latency.p95_ms);
    if (s.ack_latency.count > 0) t.ack_medians.push_back(s.ack_latency.median_ms);
  }
  std::sort(t.ack_medians.begin(), t.ack_medians.end());
  return t;
}

std::string Team::ProgressLine() const {
  const Totals s = Sum();
  const double t = std::chrono::duration<double>(Clock::now() - started_).count();
  char line[256];
  std::snprintf(line, sizeof line,
                "fleet %6.1f s  agents %zu (%d matched)  keyframes sent %llu acked %llu unacked %llu resent %llu  "
                "shared back %llu  up %.1f MB down %.1f MB",
                t, members_.size(), s.matched, static_cast<unsigned long long>(s.sent),
                static_cast<unsigned long long>(s.acked), static_cast<unsigned long long>(s.unacked),
                static_cast<unsigned long long>(s.resent), static_cast<unsigned long long>(s.shared), s.up / 1e6,
                s.down / 1e6);
  return line;
}

nlohmann::json Team::Summary() const {
  const double wall_s = std::max(1e-3, std::chrono::duration<double>(Clock::now() - started_).count());
  nlohmann::json agents = nlohmann::json::array();
  for (const Member& m : members_) {
    if (!m.comm) continue;
    const Traffic t = SumTraffic(m.comm->Traffic());
    const double flown_s = std::max(1e-3, m.source->duration_s() / options_.speed);
    agents.push_back({{"id", m.id},
                      {"name", m.name},
                      {"recording", options_.recordings[m.recording]},
                      {"recorded_s", m.source->duration_s()},
                      {"link", agent::LinkSummaryJson(*m.comm)},
                      {"server_points_received", m.source->server_points_received()},
                      {"up_bytes", t.up_bytes},
                      {"down_bytes", t.down_bytes},
                      {"up_mb_per_s", t.up_bytes / 1e6 / flown_s},
                      {"down_mb_per_s", t.down_bytes / 1e6 / flown_s}});
  }
  const Totals s = Sum();
  const double n = static_cast<double>(std::max<size_t>(1, members_.size()));
  const double flight_s = std::max(1e-3, duration_s());
  nlohmann::json totals = {
      {"agents", members_.size()},
      {"wall_s", wall_s},
      {"kfs_sent", s.sent},
      {"kfs_acked", s.acked},
      {"kfs_unacked", s.unacked},
      {"kfs_resent", s.resent},
      {"drain_s", drain_s_},
      {"ack_ms_median_of_agents", s.ack_medians.empty() ? 0.0 : s.ack_medians[s.ack_medians.size() / 2]},
      {"ack_ms_p95_worst_agent", s.ack_p95_max},
      {"up_mb_per_s_per_agent", s.up / 1e6 / flight_s / n},
      {"down_mb_per_s_per_agent", s.down / 1e6 / flight_s / n}};
  return {{"totals", totals}, {"agents", agents}};
}

report::RunResult Team::ResultFromMaps(const ServerBackend& backend) const {
  return replay::ResultFromBackend(merged_, backend);
}

}  // namespace ccm::fleet
