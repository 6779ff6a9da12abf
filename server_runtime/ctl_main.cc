// ccm_ctl: operator commands for a running ccm_server, over DDS. `ccm_ctl status` joins the
// domain, waits for the latest ccm/server_status sample (TRANSIENT_LOCAL: the server's last
// one arrives as soon as the endpoints match) and prints it. Exit code 0 on a sample, 1 when
// no server answered within --timeout, 2 on bad input.
#include <CLI/CLI.hpp>

#include <chrono>
#include <iostream>

#include "idl/ccm_statusPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/logging.h"
#include "runtime_common/topics.h"
#include "runtime_common/typed_endpoints.h"
#include "server_runtime/status_format.h"

int main(int argc, char** argv) {
  using namespace ccm;
  rt::SessionOptions session_options;
  session_options.participant_name = "ccm_ctl";
  double timeout_s = 5.0;
  bool json = false;
  CLI::App app{"ccm_ctl: inspect a running ccm_server over DDS"};
  app.require_subcommand(1);
  auto* status = app.add_subcommand("status", "print the server's status: agents, maps, fusions, queues, traffic");
  for (CLI::App* sub : {status}) {
    sub->add_option("--domain", session_options.domain_id, "DDS domain id of the server")->capture_default_str();
    sub->add_option("--qos", session_options.qos_file,
                    "Fast DDS XML QoS profiles file (the server's: same discovery settings)");
    sub->add_option("--participant-profile", session_options.participant_profile,
                    "participant profile in the QoS file (discovery server: ccm_participant_ds_client)")
        ->capture_default_str();
    sub->add_option("--security-dir", session_options.security_dir,
                    "DDS-Security files of the operator (make-pki.sh output ctl/; docs/security.md)");
    sub->add_option("--timeout", timeout_s, "wait this long for the server [s]")->capture_default_str();
  }
  status->add_flag("--json", json, "print JSON instead of text");
  CLI11_PARSE(app, argc, argv);

  std::string error;
  if (!rt::SetupLogging("warn", &error)) {
    std::cerr << "ccm_ctl: error: " << error << "\n";
    return 2;
  }
  auto session = rt::DdsSession::Create(session_options, &error);
  if (!session) {
    std::cerr << "ccm_ctl: error: " << error << "\n";
    return 2;
  }
  using Reader = rt::TypedReader<status::ServerStatusPubSubType>;
  auto reader = Reader::Create(*session, rt::kTopicServerStatus, rt::kProfileServerStatusReader,
                               Reader::QueueOptions{4, rt::OverflowPolicy::kDropOldest}, &error);
  if (!reader) {
    std::cerr << "ccm_ctl: error: " << error << "\n";
    return 2;
  }
  const auto wait = std::chrono::milliseconds(static_cast<int64_t>(timeout_s * 1000.0));
  auto sample = reader->Pop(wait);
  if (!sample) {
    std::cerr << "ccm_ctl: no server status on domain " << session_options.domain_id << " within " << timeout_s
              << " s (" << (reader->matched() > 0 ? "a server matched but sent nothing" : "no server matched")
              << "; same --domain and --qos as the server? see docs/troubleshooting.md)\n";
    return 1;
  }
  if (json) {
    std::cout << server::StatusToJson(*sample).dump(2) << std::endl;
  } else {
    std::cout << server::StatusToText(*sample);
  }
  return 0;
}
