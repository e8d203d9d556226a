// vbutcher: the command-line front of VirtualButcher's libraries. No algorithm lives here.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <string>

#include "io/error.h"
#include "perception/synthetic_set.h"
#include "tools/bench_command.h"
#include "tools/morph_command.h"

int main(int argc, char** argv) {
  CLI::App app{"VirtualButcher command-line tool"};
  app.require_subcommand(1);

  vb::perception::SyntheticSetOptions synth;
  CLI::App* synth_cmd = app.add_subcommand("synth",
                                           "Write a synthetic lamb-carcass set: annotated "
                                           "template, posed targets and their ground truth");
  synth_cmd->add_option("--out", synth.out_dir, "Output directory (created if missing)")
      ->required();
  synth_cmd->add_option("--count", synth.count, "Number of targets")->capture_default_str();
  synth_cmd->add_option("--seed", synth.seed, "Random seed; the same seed writes the same files")
      ->capture_default_str();
  synth_cmd
      ->add_option("--sigma-mm", synth.sigma_mm,
                   "Noise along the surface normal, standard deviation in mm")
      ->capture_default_str();
  synth_cmd->add_flag("--cloud", synth.cloud, "Also write a sampled point cloud per target");
  synth_cmd->add_flag("--missing", synth.missing_regions,
                      "Clouds lack what a 4-camera ring would miss, plus holes");
  synth_cmd
      ->add_option("--cloud-points", synth.cloud_points, "Points sampled per cloud before removal")
      ->capture_default_str();
  bool upright = false;
  synth_cmd->add_flag("--upright", upright,
                      "Keep targets hanging upright instead of placing them arbitrarily");

  vb::tools::MorphCommandOptions morph;
  CLI::App* morph_cmd =
      app.add_subcommand("morph", "Morph a template mesh onto a target mesh or point cloud");
  morph_cmd
      ->add_option("--template", morph.template_path, "Closed template mesh (.ply, .off, .obj)")
      ->required();
  morph_cmd
      ->add_option("--target", morph.target_path,
                   "Target mesh or cloud (.ply, .off, .obj, .pcd, .xyz)")
      ->required();
  morph_cmd->add_option("--out", morph.out_path, "Deformed template (.ply, .off, .obj)")
      ->required();
  morph_cmd->add_option("--stage", morph.stage, "coarse | full")->capture_default_str();
  morph_cmd->add_option("--report", morph.report_path,
                        "JSON report of timings, features, association, solver");
  morph_cmd->add_option("--annotations", morph.annotations_path,
                        "Template cut annotations (vbutcher-annotations YAML); needs --stage full");
  morph_cmd->add_option("--cuts", morph.cuts_path,
                        "Transferred cut planes, lines, confidence and part measures (JSON)");

  vb::tools::BenchOptions bench;
  CLI::App* bench_cmd = app.add_subcommand(
      "bench", "Accuracy and speed of the morph on synthetic targets with ground truth");
  bench_cmd->add_option("stage", bench.stage, "Stage to measure: coarse | full")
      ->capture_default_str();
  bench_cmd->add_option("--pairs", bench.pairs, "Lamb targets per noise level")
      ->capture_default_str();
  bench_cmd->add_option("--sigmas-mm", bench.sigmas_mm, "Noise levels")
      ->delimiter(',')
      ->capture_default_str();
  bench_cmd->add_option("--seed", bench.seed, "Seed of the targets")->capture_default_str();
  bench_cmd->add_flag("--clouds", bench.clouds, "Also sampled clouds with missing regions");
  bench_cmd
      ->add_option("--shapes", bench.shapes,
                   "Extra closed meshes (e.g. CGAL's cow.off), re-posed by bends")
      ->check(CLI::ExistingFile);
  bench_cmd
      ->add_option("--shape-pairs", bench.shape_pairs, "Targets per extra shape and noise level")
      ->capture_default_str();
  bench_cmd
      ->add_option("--template-features", bench.template_features,
                   "Template skeleton: levelset | mcf")
      ->capture_default_str();
  bench_cmd->add_option("--csv", bench.csv, "One row per morph (default bench_<stage>.csv)");

  CLI11_PARSE(app, argc, argv);
  try {
    if (synth_cmd->parsed()) {
      synth.arbitrary_orientation = !upright;
      const auto summary = vb::perception::WriteSyntheticSet(synth);
      std::fputs(vb::perception::FormatSummary(summary).c_str(), stdout);
    }
    if (morph_cmd->parsed()) return vb::tools::RunMorphCommand(morph);
    if (bench_cmd->parsed()) return vb::tools::RunBenchCommand(bench);
  } catch (const vb::InputError& e) {
    std::fprintf(stderr, "vbutcher: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vbutcher: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
