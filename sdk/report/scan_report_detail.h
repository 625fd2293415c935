// What scan_report.cpp and scan_report_deformation.cpp share to build report.html: HTML and
// report.json helpers, and the deformation section's parts. Internal to sls_report.
#pragma once

#include <cstddef>
#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sdk/report/scan_report.h"

namespace sls::report::detail {

std::string escape_html(const std::string& text);
// The value at a path of keys, or nullptr.
const nlohmann::json* find_key(const nlohmann::json& object, std::initializer_list<const char*> path);
std::optional<double> number_at(const nlohmann::json& object, std::initializer_list<const char*> path);
std::string text_of(const nlohmann::json& value);
// <tr><th>name</th><td>value</td></tr>, both escaped.
void add_row(std::string& html, const std::string& name, const std::string& value);

// The deformation section (scan_report_deformation.cpp): whether there is one, its tables
// (the graph, the loop closure; the quality with and without deformation), and the recording
// frame numbers of the fused poses (from report["per_frame"]).
bool has_deformation(const ScanReportInputs& inputs);
void deformation_tables(std::string& html, const nlohmann::json& report);
void deformation_quality_table(std::string& html, const nlohmann::json& report);
std::vector<std::size_t> fused_frame_numbers(const nlohmann::json& report, std::size_t poses);

}  // namespace sls::report::detail
