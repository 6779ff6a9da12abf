// What the command lines of ccm_agent and ccm_server share: the DDS participant's options
// (which win over the config file's keys when given), the fault-injection options, and the
// DDS session they resolve to. Templates over the runtime's config type, which has the
// fields domain_id, qos_file, security_dir, insecure, log_level and participant_profile.
#pragma once

#include <CLI/CLI.hpp>
#include <glog/logging.h>
#include <spdlog/spdlog.h>

#include <string>

#include "runtime_common/dds_session.h"

namespace ccm::rt {

/// The DDS options of a command line; each is "given" when set there.
struct DdsOptionsGiven {
  CLI::Option *domain = nullptr, *qos = nullptr, *security = nullptr, *insecure = nullptr, *log = nullptr,
              *participant = nullptr;
};

template <class Config>
DdsOptionsGiven AddDdsOptions(CLI::App* app, Config* c, SessionOptions* session) {
  DdsOptionsGiven g;
  g.domain = app->add_option("--domain", c->domain_id, "DDS domain id (overrides the config)");
  g.qos = app->add_option("--qos", c->qos_file, "Fast DDS XML QoS profiles file (overrides the config)");
  g.security = app->add_option("--security-dir", c->security_dir,
                               "DDS-Security directory of this participant (docs/security.md; overrides the config)");
  g.insecure = app->add_flag("--insecure", c->insecure,
                             "run without DDS-Security although the config names a security_dir (the packaged "
                             "configs do): anyone on the network can read the map and forge acknowledgements");
  g.log = app->add_option("--log-level", c->log_level, "trace, debug, info, warn, error, off");
  g.participant = app->add_option("--participant-profile", c->participant_profile,
                                  "participant profile in the QoS file (discovery server: ccm_participant_ds_client)");
  app->add_option("--drop", session->fault.drop_probability, "fault injection: drop probability of received datagrams");
  app->add_option("--delay-ms", session->fault.delay_ms, "fault injection: delay of received datagrams [ms]");
  app->add_option("--cut-at", session->fault.outage_at_s,
                  "fault injection: cut this participant's link this many seconds after it started (with --cut-s)");
  app->add_option("--cut-s", session->fault.outage_s, "fault injection: length of the link cut [s]: nothing in or out");
  app->add_option("--rate-cap", session->fault.rate_kb_s,
                  "fault injection: cap on received bytes [kB/s]; a full 0.5 s buffer drops (CCM_FAULT_QUEUE_MS)");
  return g;
}

/// After `merged` took the config file's keys: the DDS options given on the command line
/// (`cli`) win.
template <class Config>
void KeepGivenDdsOptions(const DdsOptionsGiven& g, const Config& cli, Config* merged) {
  if (*g.domain) merged->domain_id = cli.domain_id;
  if (*g.qos) merged->qos_file = cli.qos_file;
  if (*g.security) merged->security_dir = cli.security_dir;
  if (*g.insecure) merged->insecure = cli.insecure;
  if (*g.log) merged->log_level = cli.log_level;
  if (*g.participant) merged->participant_profile = cli.participant_profile;
}

/// The session's participant options from the config; fault injection from the environment
/// (CCM_FAULT_*) unless the command line set it.
template <class Config>
bool ResolveSession(const Config& c, SessionOptions* session, std::string* error) {
  if (!session->fault.enabled()) {
    auto env = FaultOptions::FromEnvironment(error);
    if (!env) return false;
    session->fault = *env;
  }
  session->domain_id = c.domain_id;
  session->qos_file = c.qos_file;
  session->security_dir = c.insecure ? std::string() : c.security_dir;
  if (c.insecure && !c.security_dir.empty()) {
    spdlog::warn("DDS-Security is off (insecure): security_dir '{}' is not used; anyone on DDS domain {} can read "
                 "this participant's data and write as it",
                 c.security_dir, c.domain_id);
  }
  session->participant_profile = c.participant_profile;
  return true;
}

/// glog, which Ceres logs through, set up for a process that runs unattended:
/// - Ceres reports rejected trust-region steps (a point behind a camera) as glog warnings:
///   expected during optimization, noise for an operator. Keep its errors, on stderr.
/// - A crash (SIGSEGV, SIGABRT from an uncaught exception or a failed check, SIGBUS, SIGFPE,
///   SIGILL) prints the signal and a symbolized stack trace on stderr, then the process dies
///   the default way (same exit status, core dump if enabled): a daemon that dies in the
///   field or in a live test says where, not just "killed by a signal".
inline void SetUpGlog(const char* argv0) {
  google::InitGoogleLogging(argv0);
  FLAGS_minloglevel = google::GLOG_ERROR;
  FLAGS_logtostderr = true;
  google::InstallFailureSignalHandler();
}

}  // namespace ccm::rt
