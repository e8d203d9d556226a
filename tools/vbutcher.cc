// vbutcher: the command-line front of VirtualButcher's libraries. No algorithm lives here.
#include <cstdio>
#include <exception>
#include <string>

#include <CLI/CLI.hpp>

#include "io/error.h"
#include "perception/synthetic_set.h"

int main(int argc, char** argv) {
  CLI::App app{"VirtualButcher command-line tool"};
  app.require_subcommand(1);

  vb::perception::SyntheticSetOptions synth;
  CLI::App* synth_cmd = app.add_subcommand(
      "synth", "Write a synthetic lamb-carcass set: annotated template, posed targets and their ground truth");
  synth_cmd->add_option("--out", synth.out_dir, "Output directory (created if missing)")->required();
  synth_cmd->add_option("--count", synth.count, "Number of targets")->capture_default_str();
  synth_cmd->add_option("--seed", synth.seed, "Random seed; the same seed writes the same files")->capture_default_str();
  synth_cmd->add_option("--sigma-mm", synth.sigma_mm, "Noise along the surface normal, standard deviation in mm")
      ->capture_default_str();
  synth_cmd->add_flag("--cloud", synth.cloud, "Also write a sampled point cloud per target");
  synth_cmd->add_flag("--missing", synth.missing_regions, "Clouds lack what a 4-camera ring would miss, plus holes");
  synth_cmd->add_option("--cloud-points", synth.cloud_points, "Points sampled per cloud before removal")
      ->capture_default_str();
  bool upright = false;
  synth_cmd->add_flag("--upright", upright, "Keep targets hanging upright instead of placing them arbitrarily");

  CLI11_PARSE(app, argc, argv);
  try {
    if (synth_cmd->parsed()) {
      synth.arbitrary_orientation = !upright;
      const auto summary = vb::perception::WriteSyntheticSet(synth);
      std::fputs(vb::perception::FormatSummary(summary).c_str(), stdout);
    }
  } catch (const vb::InputError& e) {
    std::fprintf(stderr, "vbutcher: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vbutcher: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
