#include "perception/fusion.h"

#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "io/error.h"
#include "geometry/mesh_measures.h"
#include "morph/point_index.h"
#include "perception/depth_noise.h"
#include "perception/depth_renderer.h"
#include "perception/virtual_rig.h"
#include "tests/support/allocation_counter.h"
#include "morph/surface_distance.h"

namespace vb::perception {
namespace {

// The default 4-camera ring around a hanging synthetic carcass; frames rendered with the
// PrimeSense model, as the virtual driver renders them.
class FusionTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    carcass_ = std::make_unique<PosedCarcass>(HangCarcass(BuildCarcassTemplate(), 5));
  }
  static void TearDownTestSuite() { carcass_.reset(); }

  void SetUp() override {
    rig_ = MakeRingRig({});
    for (std::size_t c = 0; c < rig_.cameras.size(); ++c) {
      const CameraCalibration& cam = rig_.cameras[c];
      DepthRenderer renderer(cam.intrinsics, cam.X_RigCam);
      renderer.Render(carcass_->mesh, -2.2);
      clean_.push_back(renderer.depth_m());
      DepthNoise noise({}, 11 + c);
      images_.emplace_back(renderer.depth_m().size());
      noise.Apply(renderer.depth_m(), renderer.cos_incidence(), cam.intrinsics.width,
                  cam.intrinsics.height, &images_.back());
    }
  }

  std::vector<DepthView> Views() const {
    std::vector<DepthView> views;
    for (std::size_t c = 0; c < images_.size(); ++c)
      views.push_back({static_cast<int>(c), images_[c].data(), rig_.cameras[c].intrinsics.width,
                       rig_.cameras[c].intrinsics.height});
    return views;
  }

  // Template vertices some camera sees (in its image, facing it, not occluded).
  std::vector<int> VisibleVertices() const {
    const geometry::TriangleMesh& mesh = carcass_->mesh;
    const Eigen::Matrix3Xd normals = geometry::VertexNormals(mesh);
    std::vector<int> visible;
    for (int i = 0; i < mesh.num_vertices(); ++i) {
      for (std::size_t c = 0; c < rig_.cameras.size(); ++c) {
        const CameraCalibration& cam = rig_.cameras[c];
        const Eigen::Vector3d p_Cam = cam.X_RigCam.inverse() * mesh.V.col(i);
        const Eigen::Vector3d to_camera = cam.X_RigCam.translation() - mesh.V.col(i);
        if (normals.col(i).dot(to_camera) <= 0 || p_Cam.z() <= 0) continue;
        const int u = static_cast<int>(
            std::lround(cam.intrinsics.fx * p_Cam.x() / p_Cam.z() + cam.intrinsics.cx));
        const int v = static_cast<int>(
            std::lround(cam.intrinsics.fy * p_Cam.y() / p_Cam.z() + cam.intrinsics.cy));
        if (u < 0 || v < 0 || u >= cam.intrinsics.width || v >= cam.intrinsics.height) continue;
        const float z = clean_[c][static_cast<std::size_t>(v * cam.intrinsics.width + u)];
        if (z > 0 && p_Cam.z() < z + 0.005) {
          visible.push_back(i);
          break;
        }
      }
    }
    return visible;
  }

  static inline std::unique_ptr<PosedCarcass> carcass_;
  RigCalibration rig_;
  std::vector<std::vector<float>> clean_;
  std::vector<std::vector<std::uint16_t>> images_;
};

TEST_F(FusionTest, FusedCloudLiesOnTheSurfaceAndCoversWhatTheCamerasSee) {
  Fusion dut(rig_, {});
  FusedCloud cloud = dut.MakeOutput();
  const std::vector<DepthView> views = Views();
  const FusionStats stats = dut.Fuse(views, &cloud);
  ASSERT_GT(cloud.size, 10000);
  EXPECT_EQ(stats.images, 4);
  EXPECT_EQ(stats.pixel_stride, 1);

  // Mean distance to the true surface: the target is 3 mm.
  const morph::SurfaceDistance distance(carcass_->mesh);
  double sum = 0;
  int outward = 0;
  const Eigen::Matrix3Xd normals = geometry::VertexNormals(carcass_->mesh);
  const morph::PointIndex vertices(carcass_->mesh.V);
  for (int i = 0; i < cloud.size; ++i) {
    sum += distance(cloud.points.col(i));
    const int nearest = vertices.Nearest(cloud.points.col(i));
    outward += cloud.normals.col(i).dot(normals.col(nearest)) > 0;
  }
  const double mean_mm = 1000 * sum / cloud.size;
  int far = 0;
  for (int i = 0; i < cloud.size; ++i) far += distance(cloud.points.col(i)) > 0.01;
  std::printf("%d of %d fused points are more than 1 cm off the surface\n", far, cloud.size);
  EXPECT_LT(mean_mm, 3.0);
  // Normals turned towards the cameras are outward ones.
  EXPECT_GT(static_cast<double>(outward) / cloud.size, 0.97);

  // Coverage of the visible surface: a fused point within 1.5 voxels of the vertex.
  const std::vector<int> visible = VisibleVertices();
  ASSERT_GT(visible.size(), 1000u);
  const Eigen::Matrix3Xd fused = cloud.points.leftCols(cloud.size);
  const morph::PointIndex index(fused);
  int covered = 0;
  for (int v : visible) {
    const Eigen::Vector3d p = carcass_->mesh.V.col(v);
    covered += (fused.col(index.Nearest(p)) - p).norm() < 1.5 * dut.options().voxel_m;
  }
  const double coverage = static_cast<double>(covered) / visible.size();
  EXPECT_GT(coverage, 0.90);
  RecordProperty("mean_distance_mm", std::to_string(mean_mm));
  RecordProperty("coverage", std::to_string(coverage));
  std::printf("mean distance %.2f mm, coverage %.1f %% of %zu visible vertices, %d points\n",
              mean_mm, 100 * coverage, visible.size(), cloud.size);
}

TEST_F(FusionTest, CountsReadingsOnImageBordersWhenTheCarcassLeavesTheView) {
  // The default ring sees the whole carcass: nothing of it on the images' edges.
  {
    Fusion dut(rig_, {});
    FusedCloud cloud = dut.MakeOutput();
    EXPECT_EQ(dut.Fuse(Views(), &cloud).border_readings, 0);
  }
  // Cameras 0.9 m from the axis see about 0.8 m of a 1.2 m carcass: both ends cross the
  // image edges.
  RingRigOptions close;
  close.radius_m = 0.9;
  const RigCalibration rig = MakeRingRig(close);
  std::vector<std::vector<std::uint16_t>> images;
  std::vector<DepthView> views;
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    const CameraCalibration& cam = rig.cameras[c];
    DepthRenderer renderer(cam.intrinsics, cam.X_RigCam);
    renderer.Render(carcass_->mesh, -2.2);
    images.emplace_back(renderer.depth_m().size());
    DepthNoise({}, 11 + c)
        .Apply(renderer.depth_m(), renderer.cos_incidence(), cam.intrinsics.width,
               cam.intrinsics.height, &images.back());
  }
  for (std::size_t c = 0; c < images.size(); ++c)
    views.push_back({static_cast<int>(c), images[c].data(), rig.cameras[c].intrinsics.width,
                     rig.cameras[c].intrinsics.height});
  Fusion dut(rig, {});
  FusedCloud cloud = dut.MakeOutput();
  const FusionStats stats = dut.Fuse(views, &cloud);
  EXPECT_GT(stats.border_readings, 1000);
  EXPECT_LT(stats.border_readings, stats.roi_readings);
}

TEST_F(FusionTest, CropsToTheRegionOfInterest) {
  FusionOptions options;
  options.roi =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.6, -0.6, -0.8), Eigen::Vector3d(0.6, 0.6, 0));
  Fusion dut(rig_, options);
  FusedCloud cloud = dut.MakeOutput();
  const FusionStats stats = dut.Fuse(Views(), &cloud);
  EXPECT_LT(stats.roi_readings, stats.valid_readings);
  for (int i = 0; i < cloud.size; ++i)
    EXPECT_TRUE(options.roi.contains(cloud.points.col(i))) << cloud.points.col(i).transpose();
}

TEST_F(FusionTest, RemovesIsolatedSpecks) {
  // Flying pixels: 300 readings scattered through the ROI, away from the carcass.
  std::mt19937 rng(4);
  std::uniform_int_distribution<int> pixel(0, 640 * 480 - 1);
  std::uniform_int_distribution<int> depth_mm(500, 700);
  int planted = 0;
  for (int k = 0; k < 300; ++k) {
    const int i = pixel(rng);
    if (images_[0][static_cast<std::size_t>(i)] != 0) continue;
    images_[0][static_cast<std::size_t>(i)] = static_cast<std::uint16_t>(depth_mm(rng));
    ++planted;
  }
  Fusion dut(rig_, {});
  FusedCloud cloud = dut.MakeOutput();
  const FusionStats stats = dut.Fuse(Views(), &cloud);
  EXPECT_GE(stats.outliers, planted * 9 / 10);
  const morph::SurfaceDistance distance(carcass_->mesh);
  int far = 0;
  for (int i = 0; i < cloud.size; ++i) far += distance(cloud.points.col(i)) > 0.05;
  EXPECT_LT(far, planted / 20);
}

TEST_F(FusionTest, StaysWithinItsBudgetByDecimating) {
  FusionOptions options;
  options.max_points = 20000;  // far fewer than the ~45,000 voxels the carcass fills
  Fusion dut(rig_, options);
  FusedCloud cloud = dut.MakeOutput();
  const FusionStats stats = dut.Fuse(Views(), &cloud);
  EXPECT_GT(stats.pixel_stride, 1);
  EXPECT_LE(cloud.size, options.max_points);
  EXPECT_GT(cloud.size, options.max_points / 3);
  EXPECT_EQ(cloud.points.cols(), options.max_points);  // the buffer never grew
}

TEST_F(FusionTest, SteadyStateFusionAllocatesNothing) {
  Fusion dut(rig_, {});
  FusedCloud cloud = dut.MakeOutput();
  const std::vector<DepthView> views = Views();
  dut.Fuse(views, &cloud);  // warm-up
  const test::AllocationScope allocations;
  for (int k = 0; k < 3; ++k) dut.Fuse(views, &cloud);
  EXPECT_EQ(allocations.count(), 0);
}

TEST_F(FusionTest, SkipsImagesThatDoNotFitTheCalibration) {
  Fusion dut(rig_, {});
  FusedCloud cloud = dut.MakeOutput();
  std::vector<DepthView> views = Views();
  views[1].width = 320;  // wrong size
  views[2].camera = 9;   // no such camera
  views[3].depth_mm = nullptr;
  const FusionStats stats = dut.Fuse(views, &cloud);
  EXPECT_EQ(stats.images, 1);
  EXPECT_EQ(stats.skipped_images, 3);
  EXPECT_GT(cloud.size, 1000);
}

TEST(FusionOptionsTest, RefusesUnusableOptions) {
  const RigCalibration rig = MakeRingRig({});
  FusionOptions options;
  options.voxel_m = 0;
  EXPECT_THROW(Fusion(rig, options), InputError);
  options = {};
  options.max_points = 10;
  EXPECT_THROW(Fusion(rig, options), InputError);
  options = {};
  options.roi = Eigen::AlignedBox3d(Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(0, 0, 0));
  EXPECT_THROW(Fusion(rig, options), InputError);
}

}  // namespace
}  // namespace vb::perception
