#include "perception/virtual_rig.h"

#include "io/mesh_io.h"

namespace vb::perception {

PosedCarcass HangCarcass(const CarcassTemplate& carcass, std::uint64_t seed, double angle_scale) {
  PoseOptions pose_options;
  pose_options.arbitrary_orientation = false;
  pose_options.angle_scale = angle_scale;
  PosedCarcass posed = PoseCarcass(carcass, SampleCarcassPose(seed, pose_options));
  const Eigen::Vector3d top = posed.mesh.V.rowwise().maxCoeff();
  const Eigen::Vector3d bottom = posed.mesh.V.rowwise().minCoeff();
  const Eigen::Vector3d shift(-0.5 * (top.x() + bottom.x()), -0.5 * (top.y() + bottom.y()),
                              -top.z());
  posed.mesh.V.colwise() += shift;
  for (geometry::Plane& plane : posed.cut_planes) plane.point += shift;
  for (Eigen::Vector3d& p : posed.pivots) p += shift;
  for (Eigen::Vector3d& p : posed.tails) p += shift;
  posed.centre_world += shift;
  return posed;
}

VirtualRigFiles WriteVirtualRig(const CarcassTemplate& carcass, const VirtualRigOptions& options) {
  std::filesystem::create_directories(options.out_dir);
  VirtualRigFiles files;
  files.rig = options.out_dir / "rig.yaml";
  files.carcass = options.out_dir / "carcass.ply";
  files.scene = options.out_dir / "scene.yaml";
  files.truth = HangCarcass(carcass, options.carcass_seed);
  SaveRigCalibration(files.rig, MakeRingRig(options.ring));
  io::WriteMesh(files.carcass, files.truth.mesh);
  VirtualScene scene;
  scene.rig_path = "rig.yaml";
  scene.carcass_path = "carcass.ply";
  scene.fps = options.fps;
  scene.floor_z_m = options.floor_z_m;
  scene.noise.enabled = options.noise;
  scene.seed = options.carcass_seed;
  SaveVirtualScene(files.scene, scene);
  return files;
}

VirtualLine::VirtualLine(const CarcassTemplate* carcass, std::filesystem::path scene_path)
    : carcass_(carcass), scene_path_(std::move(scene_path)), scene_(LoadVirtualScene(scene_path_)) {
  scene_.rig_path = std::filesystem::relative(scene_.rig_path, scene_path_.parent_path());
}

PosedCarcass VirtualLine::Hang(std::uint64_t seed) {
  PosedCarcass posed = HangCarcass(*carcass_, seed);
  const std::string name = "carcass_" + std::to_string(seed) + ".ply";
  io::WriteMesh(scene_path_.parent_path() / name, posed.mesh);
  scene_.carcass_path = name;
  SaveVirtualScene(scene_path_, scene_);
  return posed;
}

void VirtualLine::Clear() {
  scene_.carcass_path.clear();
  SaveVirtualScene(scene_path_, scene_);
}

}  // namespace vb::perception
