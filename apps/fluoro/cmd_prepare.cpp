// fluoro prepare: the CT-only part of a registration's preparation (bone mesh, bone attenuation,
// the fine stages' gradient fields), computed once before surgery and saved, so that `register`
// and `sweep` load it with --prepared instead of recomputing it (docs/cli.md, "fluoro prepare").
#include <cstdio>
#include <filesystem>
#include <optional>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/prepared_ct_arguments.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/volume_io.hpp"
#include "kernels/backend_registry.hpp"

namespace fluoro::cli {
namespace {

struct PrepareOptions {
  PreparationArguments prep;
  std::string out, backend = "cpu";
};

void run(const PrepareOptions& o) {
  check_output_path(o.out);
  validate_preparation_arguments(o.prep);
  auto backend = make_backend(o.backend);
  // Before the costly part: a backend that cannot save its volumes says so now.
  if (!backend->can_save_volumes())
    throw_input_error("--backend", "the " + std::string(backend->name()) +
                                       " backend cannot save prepared volumes; prepare and register with --backend cpu");
  StageTimer timer;
  const Volume hu = read_volume(o.prep.ct);
  std::optional<Volume> mask;
  if (!o.prep.mask.empty()) mask = read_volume(o.prep.mask);
  const double read_seconds = timer.lap("read");
  const RegistrationOptions options = registration_options(o.prep);
  const PreparedCt ct = prepare_ct(*backend, hu, options, mask ? &*mask : nullptr);
  const PreparedCtSource source = prepared_ct_source(o.prep, options);
  const double prepare_seconds = timer.lap("prepare");
  write_prepared_ct(o.out, *backend, ct, source);
  const double write_seconds = timer.lap("write");
  if (!quiet()) {
    std::error_code ec;
    const double mb = double(std::filesystem::file_size(o.out, ec)) / 1e6;
    std::printf("%s: %.1f MB (bone mesh of %zu triangles, %zu gradient fields, %s backend); read %.2f s, prepared "
                "%.2f s, written %.2f s\n",
                o.out.c_str(), mb, ct.mesh.triangles.size(), ct.gradients.size(), std::string(backend->name()).c_str(),
                read_seconds, prepare_seconds, write_seconds);
  }
}

}  // namespace

void add_prepare_command(CLI::App& app) {
  auto o = std::make_shared<PrepareOptions>();
  auto* cmd = app.add_subcommand(
      "prepare", "Prepare a CT for registration once (bone mesh, gradient fields); register/sweep take --prepared");
  cmd->add_option("--ct", o->prep.ct, "CT volume in HU (.nii, .nii.gz, .mha, .mhd, .nrrd, DICOM directory)")->required();
  cmd->add_option("--mask", o->prep.mask, "Bone mask volume (non-zero = bone), replaces the iso-value");
  cmd->add_option("--out", o->out, "Prepared CT file (.fluoroprep)")->required();
  cmd->add_option("--backend", o->backend, "Compute backend whose resident form is saved (cpu)")->capture_default_str();
  add_preparation_options(*cmd, o->prep);
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
