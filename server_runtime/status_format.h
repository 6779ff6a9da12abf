// Printing a ServerStatus sample (idl/ccm_status.idl) for operators: JSON (ccm_ctl status
// --json, scripts and tests) and a short human-readable table. No DDS entities here.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

#include "idl/ccm_status.h"

namespace ccm::server {

nlohmann::json StatusToJson(const status::ServerStatus& s);
std::string StatusToText(const status::ServerStatus& s);

}  // namespace ccm::server
