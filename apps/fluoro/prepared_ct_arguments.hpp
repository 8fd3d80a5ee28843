#pragma once
// The CT-side arguments that `fluoro prepare`, `fluoro register` and `fluoro sweep` share: the
// settings a prepared CT depends on, and what a prepared file must have been made from.
#include <CLI/CLI.hpp>
#include <string>

#include "pipelines/registration/prepared_ct_file.hpp"
#include "pipelines/registration/registration.hpp"

namespace fluoro::cli {

struct PreparationArguments {
  std::string ct, mask;
  double iso_hu = 250.0, tissue_hu = 100.0, mu_water = 0.02;
};

// --iso, --tissue-hu and --mu-water, with their defaults shown.
void add_preparation_options(CLI::App& cmd, PreparationArguments& a);
// Throws InputError naming the option when a value is unusable.
void validate_preparation_arguments(const PreparationArguments& a);
// The registration options those arguments set (the rest default).
RegistrationOptions registration_options(const PreparationArguments& a);
// The CT's (and mask's) digests and the preparation settings: what `prepare` records and what
// `register --prepared` checks. Throws InputError naming a CT or mask that does not exist.
PreparedCtSource prepared_ct_source(const PreparationArguments& a, const RegistrationOptions& options);

}  // namespace fluoro::cli
