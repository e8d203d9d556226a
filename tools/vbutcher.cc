// vbutcher: the command-line front of VirtualButcher's libraries. No algorithm lives here.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#include "io/error.h"
#include "io/read_limits.h"
#include "io/version.h"
#include "perception/synthetic_set.h"
#include "tools/bench_command.h"
#include "tools/bench_inputs.h"
#include "tools/bench_shapes.h"
#include "tools/calibrate_command.h"
#include "tools/capture_command.h"
#include "tools/lcm_command.h"
#include "tools/morph_command.h"
#include "tools/saw_command.h"

int main(int argc, char** argv) {
  CLI::App app{"VirtualButcher command-line tool"};
  app.require_subcommand(1);
  app.set_version_flag("--version",
                       std::string("vbutcher ") + vb::Version() + " (" + vb::GitRevision() + ")");
  app.footer(
      "Exit status: 0 done; 1 failed at run time (a device, a socket, a file that cannot be "
      "written); 2 the command line or an input file is wrong (the message names it); 3 the "
      "work did not succeed (capture: no frame set; morph: the target could not be morphed; "
      "record: a camera left out; lcm-listen: messages missing, invalid or malformed).");

  // --threads, as the morph's commands take it: the threads one morph runs on.
  const auto add_threads = [](CLI::App* command, int& threads, const std::string& help) {
    command->add_option("--threads", threads, help)
        ->check(CLI::Range(1, vb::morph::WorkerPool::kMaxThreads))
        ->capture_default_str();
  };

  // Limits on the mesh and cloud files read (io/read_limits.h), raised for offline work on
  // large scans: vbutcher --max-points 20000000 morph ...
  vb::io::ReadLimits limits;
  std::uint64_t max_file_mib = limits.max_file_bytes >> 20;
  app.add_option("--max-points", limits.max_points,
                 "Most vertices or points a mesh or cloud file may hold")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--max-faces", limits.max_faces, "Most faces a mesh file may hold")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--max-file-mib", max_file_mib, "Largest mesh or cloud file read, MiB")
      ->capture_default_str()
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{1} << 20));

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
  morph_cmd->add_option("--template", morph.template_path,
                        "Closed template mesh (.ply, .off, .obj); or --model");
  morph_cmd->add_option("--model", morph.model_path,
                        "Compiled template (vbutcher template compile), annotations included");
  morph_cmd
      ->add_option("--target", morph.target_path,
                   "Target mesh or cloud (.ply, .off, .obj, .pcd, .xyz)")
      ->required();
  morph_cmd->add_option("--out", morph.out_path, "Deformed template (.ply, .off, .obj)")
      ->required();
  morph_cmd
      ->add_option("--stage", morph.stage,
                   "full: the whole morph (coarse, dense, check, cuts); coarse: the posture "
                   "alignment alone")
      ->capture_default_str();
  morph_cmd
      ->add_option("--mesh-target", morph.mesh_target,
                   "A target mesh read as its vertices or its surface (points drawn uniformly "
                   "over its area); auto: its surface when its vertices cover it unevenly")
      ->check(CLI::IsMember({"auto", "vertices", "surface"}))
      ->capture_default_str();
  morph_cmd
      ->add_option("--target-units", morph.target_units,
                   "The target file's length unit (m, cm, mm or 100um); it is read into "
                   "metres, the deformed template written back in it")
      ->capture_default_str();
  add_threads(morph_cmd, morph.threads, "Threads the morph runs on");
  morph_cmd->add_option("--report", morph.report_path,
                        "JSON report of timings, features, association, solver");
  morph_cmd->add_option(
      "--annotations", morph.annotations_path,
      "Template cut annotations (vbutcher-annotations YAML); not with --stage coarse");
  morph_cmd->add_option("--cuts", morph.cuts_path,
                        "Transferred cut planes, lines, confidence and part measures (JSON)");
  morph_cmd
      ->add_option("--template-up", morph.template_up,
                   "Upright prior: the template's up direction (x y z); needs --target-up")
      ->expected(3);
  morph_cmd
      ->add_option("--target-up", morph.target_up,
                   "Upright prior: the target's up direction (x y z), e.g. the rig's")
      ->expected(3);
  morph_cmd
      ->add_option("--max-tilt-deg", morph.max_tilt_deg,
                   "Upright prior: placements tilted more than this are not considered")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 180.0));

  CLI::App* template_cmd =
      app.add_subcommand("template", "Compile a template model once, offline, or inspect one");
  template_cmd->require_subcommand(1);
  vb::tools::TemplateCompileOptions compile;
  CLI::App* compile_cmd = template_cmd->add_subcommand(
      "compile", "Store the template's precomputed model and its annotations in one file");
  compile_cmd->add_option("--template", compile.template_path, "Closed template mesh")->required();
  compile_cmd->add_option("--annotations", compile.annotations_path, "Cut annotations (YAML)")
      ->required();
  compile_cmd->add_option("-o,--out", compile.out_path, "Output file (.vbt)")->required();
  compile_cmd->add_option("--id", compile.id, "Template id (default: the annotations' name)");
  compile_cmd->add_option("--version", compile.version, "Template version")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  vb::tools::TemplateWrapOptions wrap;
  CLI::App* wrap_cmd = template_cmd->add_subcommand(
      "wrap", "One closed surface around any mesh (open, in pieces), to make a template of");
  wrap_cmd->add_option("--mesh", wrap.mesh_path, "Mesh to wrap (.ply, .off, .obj)")->required();
  wrap_cmd->add_option("-o,--out", wrap.out_path, "Closed surface (.ply, .off, .obj)")->required();
  wrap_cmd
      ->add_option("--alpha", wrap.wrap.alpha,
                   "Gaps narrower than this are bridged, finer detail smoothed; fraction of the "
                   "mesh's bounding-box diagonal (smaller: slower, more vertices)")
      ->check(CLI::Range(0.002, 0.5))
      ->capture_default_str();
  wrap_cmd
      ->add_option("--offset", wrap.wrap.offset,
                   "How far outside the mesh the wrap lies; fraction of the diagonal")
      ->check(CLI::Range(1e-5, 0.1))
      ->capture_default_str();
  std::filesystem::path info_path;
  CLI::App* info_cmd =
      template_cmd->add_subcommand("info", "Verify and describe a compiled template");
  info_cmd->add_option("model", info_path, "Compiled template (.vbt)")->required();

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
      ->add_option("--cloud-points", bench.cloud_points,
                   "Points sampled per cloud target before the missing regions are dropped")
      ->check(CLI::Range(100, 2000000))
      ->capture_default_str();
  bench_cmd->add_flag("--rig", bench.rig,
                      "Full stage: also clouds fused from a 4-camera virtual rig (sensor model)");
  bench_cmd
      ->add_option("--pose-scale", bench.pose_scale,
                   "The lambs' joint angle ranges times this (1: the line's poses; up to 4)")
      ->check(CLI::Range(0.0, vb::perception::kMaxAngleScale))
      ->capture_default_str();
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
  bench_cmd
      ->add_option("--min-confidence", bench.min_confidence,
                   "Full stage: a job counts as sent when every cut reaches this (the "
                   "daemon's job.min_confidence)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  bench_cmd->add_option("--dense-rounds", bench.dense_rounds, "Full stage: dense rounds")
      ->capture_default_str();
  bench_cmd->add_flag("--start-from-truth", bench.start_from_truth,
                      "Full stage: start the dense stage from node transforms fitted to the true "
                      "surface (what the dense stage's own energy does to a right answer)");
  add_threads(bench_cmd, bench.threads, "Full stage: threads a morph runs on");
  bench_cmd->add_option("--csv", bench.csv, "One row per morph (default bench_<stage>.csv)");
  bench_cmd
      ->add_option("--set", bench.profile_settings,
                   "Profile key=value for this run (any key `vbutcher template info` lists; "
                   "repeatable; overrides --dense-rounds); bench coarse takes coarse.* keys only")
      ->allow_extra_args(false);

  vb::tools::VirtualRigCommandOptions virtual_rig;
  CLI::App* virtual_rig_cmd = app.add_subcommand(
      "virtual-rig", "Write a virtual camera rig with a synthetic carcass on the hook");
  virtual_rig_cmd->add_option("--out", virtual_rig.out_dir, "Output directory")->required();
  virtual_rig_cmd->add_option("--cameras", virtual_rig.cameras, "Cameras in the ring")
      ->capture_default_str();
  virtual_rig_cmd->add_option("--radius-m", virtual_rig.radius_m, "Ring radius")
      ->check(CLI::Range(0.5, 5.0))
      ->capture_default_str();
  virtual_rig_cmd->add_option("--seed", virtual_rig.seed, "Carcass pose seed")
      ->capture_default_str();
  virtual_rig_cmd->add_option("--fps", virtual_rig.fps, "Frame rate")
      ->check(CLI::Range(1, 60))
      ->capture_default_str();
  virtual_rig_cmd->add_flag("--no-noise", virtual_rig.no_noise, "Noise-free depth");

  vb::tools::VirtualLineOptions virtual_line;
  CLI::App* virtual_line_cmd = app.add_subcommand(
      "virtual-line", "Feed a virtual rig a stream of synthetic carcasses (rewrites its scene)");
  virtual_line_cmd->add_option("--scene", virtual_line.scene_path, "Virtual scene file")
      ->required()
      ->check(CLI::ExistingFile);
  virtual_line_cmd->add_option("--count", virtual_line.count, "Carcasses")->capture_default_str();
  virtual_line_cmd->add_option("--seed", virtual_line.first_seed, "Pose seed of the first")
      ->capture_default_str();
  virtual_line_cmd->add_option("--hang-s", virtual_line.hang_s, "Seconds each hangs in the rig")
      ->check(CLI::Range(0.1, 600.0))
      ->capture_default_str();
  virtual_line_cmd->add_option("--gap-s", virtual_line.gap_s, "Seconds the hook is empty between")
      ->check(CLI::Range(0.0, 600.0))
      ->capture_default_str();
  virtual_line_cmd->add_option("--truth", virtual_line.truth_out, "Write the true cut planes here");

  vb::tools::CaptureCommandOptions capture;
  CLI::App* capture_cmd = app.add_subcommand(
      "capture", "Capture one frame set from the rig's OpenNI2 cameras and fuse it into a cloud");
  capture_cmd->add_option("--rig", capture.rig_path, "Rig calibration (vbutcher-rig YAML)")
      ->required()
      ->check(CLI::ExistingFile);
  capture_cmd->add_option("--scene", capture.scene_path, "Virtual scene (for the virtual rig)")
      ->check(CLI::ExistingFile);
  capture_cmd->add_option("--out", capture.out_path, "Fused cloud (.ply, .pcd, .xyz)")->required();
  capture_cmd->add_option("--timeout", capture.timeout_s, "Seconds to wait for frames")
      ->capture_default_str();
  capture_cmd->add_option("--voxel-mm", capture.voxel_mm, "Voxel size")->capture_default_str();
  capture_cmd->add_option("--max-points", capture.max_points, "Fused-cloud budget")
      ->capture_default_str();

  vb::tools::RecordCommandOptions record;
  CLI::App* record_cmd = app.add_subcommand(
      "record", "Record every camera of the rig to .oni files, with a playback calibration");
  record_cmd->add_option("--rig", record.rig_path, "Rig calibration")
      ->required()
      ->check(CLI::ExistingFile);
  record_cmd->add_option("--scene", record.scene_path, "Virtual scene (for the virtual rig)")
      ->check(CLI::ExistingFile);
  record_cmd->add_option("--out", record.record.out_dir, "Output directory: SERIAL.oni, rig.yaml")
      ->required();
  record_cmd->add_option("--seconds", record.record.seconds, "Length")->capture_default_str();
  record_cmd
      ->add_option("--grace-seconds", record.record.grace_seconds,
                   "How long after the take a camera's recorder may take to finish before it is "
                   "killed and the camera left out")
      ->capture_default_str();

  vb::tools::CaptureBenchOptions capture_bench;
  CLI::App* capture_bench_cmd = bench_cmd->add_subcommand(
      "capture", "Capture + fusion time per frame set, and memory over the run");
  capture_bench_cmd->add_option("--scene", capture_bench.scene_path,
                                "Virtual scene (default: a 4-camera virtual rig)");
  capture_bench_cmd->add_option("--sets", capture_bench.sets, "Frame sets")->capture_default_str();
  capture_bench_cmd->add_option("--csv", capture_bench.csv, "One row per frame set")
      ->capture_default_str();

  vb::tools::InputBenchOptions input_bench;
  CLI::App* input_bench_cmd = bench_cmd->add_subcommand(
      "inputs",
      "Peak memory and time of each file reader on the largest file its limits allow "
      "(vbutcher --max-points ... bench inputs measures other limits)");
  input_bench_cmd->add_option("--scale", input_bench.scale, "Share of each limit the files reach")
      ->check(CLI::Range(1e-6, 1.0))
      ->capture_default_str();
  input_bench_cmd->add_option("--repeats", input_bench.repeats, "Reads per file")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  input_bench_cmd->add_option("--dir", input_bench.dir, "Scratch folder (default: a temporary one)");
  input_bench_cmd->add_option("--only", input_bench.only, "Only these cases")->delimiter(',');
  input_bench_cmd->add_option("--csv", input_bench.csv, "One row per read")->capture_default_str();

  vb::tools::ShapeBenchOptions shape_bench;
  CLI::App* shape_bench_cmd = bench_cmd->add_subcommand(
      "shapes",
      "The morph on third-party rigged bodies posed by their own rigs, and synthetic lambs: "
      "identity, rigid bound, coarse, full (docs/benchmarks.md)");
  shape_bench_cmd->add_option("--csv", shape_bench.csv, "One row per shape, pair, sigma, variant, method")
      ->capture_default_str();
  shape_bench_cmd->add_option("--png", shape_bench.png, "Picture (default: the CSV's name, .png)");
  shape_bench_cmd->add_flag("--no-png", shape_bench.no_png, "Skip the picture");
  shape_bench_cmd->add_option("--sigmas-mm", shape_bench.sigmas_mm, "Noise along normals, at a 1.7 m body")
      ->delimiter(',')
      ->capture_default_str();
  shape_bench_cmd
      ->add_option("--variants", shape_bench.variants,
                   "clean, shadow (a camera shadow), clutter (stray points added), severed (a "
                   "limb's end cut off by a shadow; not by default), floor (a floor the body "
                   "rests on; not by default)")
      ->delimiter(',')
      ->capture_default_str();
  shape_bench_cmd
      ->add_option("--shapes", shape_bench.shapes,
                   "Only these (bcn, sydney, faerie, wuson, spiderblob, lamb, and the "
                   "shape file's)")
      ->delimiter(',');
  shape_bench_cmd->add_option("--shape-file", shape_bench.shape_file,
                              "Bodies of your own, rigged or vertex-animated (YAML, "
                              "docs/benchmarks.md), run besides the built-in ones");
  shape_bench_cmd->add_option("--lamb-pairs", shape_bench.lamb_pairs, "Synthetic lamb targets")
      ->capture_default_str();
  shape_bench_cmd
      ->add_option("--lamb-pose-scale", shape_bench.lamb_pose_scale,
                   "The lambs' joint angle ranges times this (1: the line's poses; up to 4)")
      ->check(CLI::Range(0.0, vb::perception::kMaxAngleScale))
      ->capture_default_str();
  shape_bench_cmd->add_option("--max-pairs", shape_bench.max_pairs, "Per shape, the first n pairs (0: all)")
      ->capture_default_str();
  shape_bench_cmd->add_option("--shadow-fraction", shape_bench.shadow_fraction,
                              "Share of the points the camera shadow removes")
      ->capture_default_str();
  shape_bench_cmd->add_option("--clutter-fraction", shape_bench.clutter_fraction,
                              "Stray points the clutter variant adds, per target point")
      ->capture_default_str();
  shape_bench_cmd
      ->add_option("--views", shape_bench.views,
                   "Depth cameras round the body in the views variant, each seeing what it faces")
      ->check(CLI::Range(1, vb::tools::ShapeBenchOptions::kMaxViews))
      ->capture_default_str();
  shape_bench_cmd->add_option("--points", shape_bench.points, "Points sampled over each target's surface")
      ->capture_default_str();
  shape_bench_cmd->add_option("--seed", shape_bench.seed, "Seed of noise and placement")->capture_default_str();
  add_threads(shape_bench_cmd, shape_bench.threads, "Threads a morph runs on");
  shape_bench_cmd->add_option("--wrap-alpha", shape_bench.wrap_alpha,
                              "Alpha wrap of the third-party models: alpha, of their diagonal")
      ->capture_default_str();
  shape_bench_cmd->add_option("--wrap-offset", shape_bench.wrap_offset,
                              "Alpha wrap: offset, of their diagonal")
      ->capture_default_str();
  shape_bench_cmd
      ->add_option("--template-features", shape_bench.template_features,
                   "Templates' skeleton: levelset (as the targets') or mcf (the paper's)")
      ->check(CLI::IsMember({"levelset", "mcf"}))
      ->capture_default_str();
  shape_bench_cmd->add_option("--export", shape_bench.export_dir,
                              "Write templates, truths and every morph there as PLY");
  shape_bench_cmd
      ->add_option("--set", shape_bench.profile_settings,
                   "Profile key=value for this run (any key `vbutcher template info` "
                   "lists; repeatable)")
      ->allow_extra_args(false);

  vb::tools::CamerasCommandOptions cameras;
  CLI::App* cameras_cmd = app.add_subcommand(
      "cameras", "List every OpenNI2 device (URI, serial, USB ids, modes) and its rig entry");
  cameras_cmd->add_option("--rig", cameras.rig_path, "Rig calibration to match devices against")
      ->check(CLI::ExistingFile);
  cameras_cmd->add_option("--scene", cameras.scene_path, "Virtual scene (for the virtual rig)")
      ->check(CLI::ExistingFile);
  cameras_cmd->add_option("--uri", cameras.uris,
                          "Also open this URI (an .oni recording): its depth mode, frames and "
                          "a rig entry with intrinsics from its field of view");

  CLI::App* calibrate_cmd = app.add_subcommand(
      "calibrate", "Calibrate the rig and the saw from depth alone (docs/operations.md, bring-up)");
  calibrate_cmd->require_subcommand(1);
  vb::tools::TargetCommandOptions target;
  CLI::App* target_cmd = calibrate_cmd->add_subcommand(
      "target", "Describe the calibration target; write its YAML or its mesh");
  target_cmd->add_option("--target", target.target_path, "Target YAML (default: the shipped one)")
      ->check(CLI::ExistingFile);
  target_cmd->add_option("--out", target.out_yaml, "Write the target's YAML");
  target_cmd->add_option("--mesh", target.out_mesh, "Write its mesh (.ply, .off, .obj)");
  target_cmd->add_option("--yaw-deg", target.yaw_deg, "The mesh turned about the rod")->capture_default_str();
  vb::tools::CalibrateCaptureOptions calibrate_capture;
  CLI::App* calibrate_capture_cmd = calibrate_cmd->add_subcommand(
      "capture", "Average a still view per camera of what hangs on the hook: OUT/SERIAL.ply");
  calibrate_capture_cmd->add_option("--rig", calibrate_capture.rig_path, "Rig calibration")
      ->required()
      ->check(CLI::ExistingFile);
  calibrate_capture_cmd->add_option("--scene", calibrate_capture.scene_path, "Virtual scene")
      ->check(CLI::ExistingFile);
  calibrate_capture_cmd->add_option("--out", calibrate_capture.out_dir, "Output folder")->required();
  calibrate_capture_cmd->add_option("--frames", calibrate_capture.frames, "Frames averaged per camera")
      ->check(CLI::Range(1, 300))
      ->capture_default_str();
  vb::tools::CalibrateRigOptions calibrate_rig;
  CLI::App* calibrate_rig_cmd = calibrate_cmd->add_subcommand(
      "rig", "Solve every camera's pose from captures of the target (the first defines the rig frame)");
  calibrate_rig_cmd->add_option("--rig", calibrate_rig.rig_path, "Starting rig (rough poses)")
      ->required()
      ->check(CLI::ExistingFile);
  calibrate_rig_cmd->add_option("--captures", calibrate_rig.captures, "Capture folders, one per position")
      ->required()
      ->check(CLI::ExistingDirectory);
  calibrate_rig_cmd->add_option("--target", calibrate_rig.target_path, "Target YAML (default: the shipped one)")
      ->check(CLI::ExistingFile);
  calibrate_rig_cmd->add_option("--out", calibrate_rig.out_path, "Calibrated rig YAML")->required();
  calibrate_rig_cmd->add_option("--max-rms-mm", calibrate_rig.max_rms_mm, "Largest residual accepted")
      ->capture_default_str();
  vb::tools::CalibrateSawOptions calibrate_saw;
  CLI::App* calibrate_saw_cmd = calibrate_cmd->add_subcommand(
      "saw", "X_SawRig from points the saw's ball was jogged to and the rig saw");
  calibrate_saw_cmd->add_option("--rig", calibrate_saw.rig_path, "Calibrated rig")
      ->required()
      ->check(CLI::ExistingFile);
  calibrate_saw_cmd->add_option("--points", calibrate_saw.points_path, "vbutcher-saw-points YAML")
      ->required()
      ->check(CLI::ExistingFile);
  calibrate_saw_cmd->add_option("--out", calibrate_saw.out_path, "Write X_SawRig (YAML)");
  calibrate_saw_cmd->add_option("--check", calibrate_saw.check_path,
                                "Check the X_SawRig in this file (daemon config or --out) instead")
      ->check(CLI::ExistingFile);
  calibrate_saw_cmd->add_option("--max-rms-mm", calibrate_saw.max_rms_mm, "Largest residual accepted")
      ->capture_default_str();

  vb::tools::CheckRigOptions check_rig;
  CLI::App* check_rig_cmd = app.add_subcommand(
      "check-rig", "With the target on the hook, check every camera against the others");
  check_rig_cmd->add_option("--rig", check_rig.rig_path, "Rig calibration")
      ->required()
      ->check(CLI::ExistingFile);
  check_rig_cmd->add_option("--scene", check_rig.scene_path, "Virtual scene")->check(CLI::ExistingFile);
  check_rig_cmd->add_option("--target", check_rig.target_path, "Target YAML (default: the shipped one)")
      ->check(CLI::ExistingFile);
  check_rig_cmd->add_option("--frames", check_rig.frames, "Frames averaged per camera")
      ->check(CLI::Range(1, 300))
      ->capture_default_str();
  check_rig_cmd->add_option("--max-offset-mm", check_rig.max_offset_mm, "A camera further off has moved")
      ->capture_default_str();
  check_rig_cmd->add_option("--max-turn-deg", check_rig.max_turn_deg, "A camera turned further has moved")
      ->capture_default_str();

  vb::tools::SawSimOptions saw_sim;
  CLI::App* saw_sim_cmd = app.add_subcommand(
      "saw-sim", "Reference band-saw controller on a CAN interface (checks, acks, safe stop)");
  auto* sim_can = saw_sim_cmd->add_option("--can", saw_sim.interface, "CAN interface, e.g. vcan0");
  auto* sim_unix = saw_sim_cmd->add_option(
      "--unix", saw_sim.unix_path,
      "Listen on this Unix socket instead (virtualbutcherd: can.interface unix:PATH)");
  sim_can->excludes(sim_unix);
  saw_sim_cmd->add_option("--seconds", saw_sim.seconds, "Stop after this long (0: on SIGTERM)")
      ->capture_default_str();
  saw_sim_cmd->add_flag("--quiet", saw_sim.quiet, "Log jobs and safe stops, not each bad frame");
  saw_sim_cmd->add_option("--ids-out", saw_sim.ids_out, "Write accepted carcass ids here");

  vb::tools::SawSendOptions saw_send;
  CLI::App* saw_send_cmd = app.add_subcommand(
      "saw-send", "Send the saw heartbeats and synthetic jobs on a CAN interface, with faults");
  saw_send_cmd->add_option("--can", saw_send.interface, "CAN interface, e.g. vcan0")->required();
  saw_send_cmd->add_option("--jobs", saw_send.jobs, "Jobs to send")->capture_default_str();
  saw_send_cmd->add_option("--fault", saw_send.fault, "none | mix")->capture_default_str();
  saw_send_cmd->add_option("--fault-rate", saw_send.fault_rate, "Per-frame fault probability")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  saw_send_cmd->add_option("--seed", saw_send.seed, "Seed of the faults")->capture_default_str();
  saw_send_cmd->add_option("--job-gap-ms", saw_send.job_gap_ms, "Pause between jobs")
      ->capture_default_str();
  saw_send_cmd->add_option("--ids-out", saw_send.ids_out, "Write the clean jobs' carcass ids here");

  vb::tools::LcmPublishOptions lcm_publish;
  CLI::App* lcm_publish_cmd = app.add_subcommand(
      "lcm-publish", "Publish the cut lines of a cuts file (from morph --cuts) on LCM");
  lcm_publish_cmd->add_option("--cuts", lcm_publish.cuts_path, "vbutcher-cuts JSON")
      ->required()
      ->check(CLI::ExistingFile);
  lcm_publish_cmd->add_option("--url", lcm_publish.url, "LCM URL")->capture_default_str();
  lcm_publish_cmd->add_option("--carcass-id", lcm_publish.carcass_id, "Carcass id")
      ->capture_default_str();
  lcm_publish_cmd->add_option("--count", lcm_publish.count, "Messages to send")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  lcm_publish_cmd->add_option("--period-ms", lcm_publish.period_ms, "Pause between messages")
      ->capture_default_str();

  vb::tools::LcmListenOptions lcm_listen;
  CLI::App* lcm_listen_cmd = app.add_subcommand(
      "lcm-listen", "Receive and check the daemon's cut lines, status and diagnostics on LCM");
  lcm_listen_cmd->add_option("--url", lcm_listen.url, "LCM URL")->capture_default_str();
  lcm_listen_cmd->add_option("--count", lcm_listen.count, "Cut-lines messages to wait for")
      ->capture_default_str();
  lcm_listen_cmd->add_option("--status-count", lcm_listen.status_count,
                             "Status messages to wait for")
      ->capture_default_str();
  lcm_listen_cmd->add_option("--diagnostic-count", lcm_listen.diagnostic_count,
                             "Diagnostics to wait for")
      ->capture_default_str();
  lcm_listen_cmd->add_flag("--status", lcm_listen.print_status,
                           "Print each status message (VB_STATUS) with its cameras");
  lcm_listen_cmd->add_flag("--diagnostics", lcm_listen.print_diagnostics,
                           "Print each diagnostic (VB_DIAGNOSTICS)");
  lcm_listen_cmd->add_option("--timeout", lcm_listen.timeout_s, "Seconds to wait")
      ->capture_default_str();

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);  // prints what is wrong
    return 2;
  }
  limits.max_file_bytes = max_file_mib << 20;
  vb::io::SetDefaultReadLimits(limits);
  try {
    if (synth_cmd->parsed()) {
      synth.arbitrary_orientation = !upright;
      const auto summary = vb::perception::WriteSyntheticSet(synth);
      std::fputs(vb::perception::FormatSummary(summary).c_str(), stdout);
    }
    if (morph_cmd->parsed()) return vb::tools::RunMorphCommand(morph);
    if (compile_cmd->parsed()) return vb::tools::RunTemplateCompile(compile);
    if (info_cmd->parsed()) return vb::tools::RunTemplateInfo(info_path);
    if (wrap_cmd->parsed()) return vb::tools::RunTemplateWrap(wrap);
    if (capture_bench_cmd->parsed()) return vb::tools::RunCaptureBench(capture_bench);
    if (shape_bench_cmd->parsed()) return vb::tools::RunShapeBench(shape_bench);
    if (input_bench_cmd->parsed()) return vb::tools::RunInputBench(input_bench);
    if (cameras_cmd->parsed()) return vb::tools::RunCameras(cameras);
    if (target_cmd->parsed()) return vb::tools::RunCalibrateTarget(target);
    if (calibrate_capture_cmd->parsed()) return vb::tools::RunCalibrateCapture(calibrate_capture);
    if (calibrate_rig_cmd->parsed()) return vb::tools::RunCalibrateRig(calibrate_rig);
    if (calibrate_saw_cmd->parsed()) return vb::tools::RunCalibrateSaw(calibrate_saw);
    if (check_rig_cmd->parsed()) return vb::tools::RunCheckRig(check_rig);
    if (bench_cmd->parsed()) return vb::tools::RunBenchCommand(bench);
    if (virtual_rig_cmd->parsed()) return vb::tools::RunVirtualRig(virtual_rig);
    if (virtual_line_cmd->parsed()) return vb::tools::RunVirtualLine(virtual_line);
    if (capture_cmd->parsed()) return vb::tools::RunCapture(capture);
    if (record_cmd->parsed()) return vb::tools::RunRecord(record);
    if (saw_sim_cmd->parsed()) return vb::tools::RunSawSim(saw_sim);
    if (saw_send_cmd->parsed()) return vb::tools::RunSawSend(saw_send);
    if (lcm_publish_cmd->parsed()) return vb::tools::RunLcmPublish(lcm_publish);
    if (lcm_listen_cmd->parsed()) return vb::tools::RunLcmListen(lcm_listen);
  } catch (const vb::InputError& e) {
    std::fprintf(stderr, "vbutcher: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vbutcher: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
