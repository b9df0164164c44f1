#pragma once
// Every tunable scalar of the vision pipeline in one table: key, range, unit and a one-line
// meaning, with the field of PipelineConfig it sets; its default is that field's initializer.
// Made from this table, and from nowhere else: the pipeline's range checks (validate_parameters),
// the daemon's YAML `vision` section, mfc-eval's `--set KEY=VALUE`, and the `vision` table of
// docs/configuration.md (pipeline_parameters_markdown; a test keeps the page equal to it).

#include <span>
#include <string>
#include <string_view>

namespace mfcd::vision {

struct PipelineConfig;

struct PipelineParameter {
  enum class Type { integer, number, boolean };
  const char* key;  // the PipelineConfig field's name (nested fields: with the struct's prefix)
  Type type;
  double min, max;      // inclusive; booleans 0..1
  const char* unit;     // "px", "mm", "DN" (grey levels), "1/px"; "" for counts, ratios and switches
  const char* meaning;  // one line, for the docs table and error messages
  // false: a diagnostic or experiment setting mfc-eval may change but a cell's configuration
  // does not offer (it allocates per cycle, or only the evaluation knows its value).
  bool cell;
  double (*get)(const PipelineConfig&);
  void (*set)(PipelineConfig&, double);

  double default_value() const;    // get(PipelineConfig{})
  bool in_range(double v) const;   // also: an integer or boolean holds a whole value
  std::string range_text() const;  // "int 1..16", "number 0..100", "bool"
};

std::span<const PipelineParameter> pipeline_parameters();
// nullptr for an unknown key.
const PipelineParameter* find_pipeline_parameter(std::string_view key);

// Sets one parameter, checked against its range. Throws std::invalid_argument naming the key,
// its range and the value, or listing the known keys for an unknown one.
void set_pipeline_parameter(PipelineConfig& config, std::string_view key, double value);
// "key=value" (booleans 0/1/true/false), as mfc-eval --set takes it; the same errors.
void apply_pipeline_setting(PipelineConfig& config, std::string_view setting);

// Every parameter within its range, and the pairs that must agree (fit_inlier_cost_px <=
// fit_score_gate_px, edges_low_threshold <= edges_high_threshold). Throws std::invalid_argument
// naming the first offending key.
void validate_parameters(const PipelineConfig& config);

// The `vision` table of docs/configuration.md: the cell's parameters, one row each.
std::string pipeline_parameters_markdown();

}  // namespace mfcd::vision
