#include "dqo_map/mesh/object_recon.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "mesh_test_util.h"

namespace dqo::mesh {
namespace {

using test_util::icosphere;

GtObject gt_sphere(uint32_t id, int class_id, const std::string& name, const Eigen::Vector3d& c,
                   double r) {
  GtObject o;
  o.id = id;
  o.class_id = class_id;
  o.class_name = name;
  o.box.centre = c;
  o.box.half_extents = Eigen::Vector3d::Constant(r);
  o.mesh = icosphere(c, r, 3);
  return o;
}

TEST(ObjectRecon, TableRowsMeanAndCropPerObject) {
  const Eigen::Vector3d c1(0, 0, 1), c2(1, 0, 1), c3(2, 0, 1);
  const std::vector<GtObject> gt = {gt_sphere(1, 41, "cup", c1, 0.1),
                                    gt_sphere(2, 56, "chair", c2, 0.1),
                                    gt_sphere(3, 41, "cup", c3, 0.1),
                                    gt_sphere(4, 60, "table", c3, 0.3)};
  // Object 10 is 1 cm outside GT 1, with a far blob that the GT box crop must drop; object 30 is
  // 2 cm outside GT 3; object 11 has no mesh; GT 4 is unmatched.
  const std::vector<ReconMatch> matches = {{10, 1}, {11, 2}, {30, 3}, {99, 77}};
  int calls = 0;
  const EstimatedMeshFn mesh_of = [&](uint64_t id) -> std::optional<TriangleMesh> {
    ++calls;
    if (id == 10) {
      return test_util::merged(icosphere(c1, 0.11, 3),
                               icosphere(c1 + Eigen::Vector3d(0, 3, 0), 0.2, 2));
    }
    if (id == 30) return icosphere(c3, 0.12, 3);
    return std::nullopt;
  };
  const ObjectReconTable table = evaluate_object_reconstructions(gt, matches, mesh_of, {});
  EXPECT_EQ(calls, 3);
  ASSERT_EQ(table.rows.size(), 4u);

  const ObjectReconRow& r1 = table.rows[0];
  EXPECT_EQ(r1.est_id, 10u);
  EXPECT_EQ(r1.gt_id, 1u);
  EXPECT_EQ(r1.class_id, 41);
  EXPECT_EQ(r1.class_name, "cup");
  ASSERT_TRUE(r1.has_mesh) << r1.note;
  EXPECT_NEAR(r1.metrics.accuracy_cm, 1.0, 0.05);  // the blob would add ~70 cm uncropped
  EXPECT_NEAR(r1.metrics.completion_cm, 1.0, 0.05);

  EXPECT_EQ(table.rows[1].est_id, 11u);
  EXPECT_FALSE(table.rows[1].has_mesh);
  EXPECT_EQ(table.rows[1].note, "no mesh");

  const ObjectReconRow& r3 = table.rows[2];
  ASSERT_TRUE(r3.has_mesh) << r3.note;
  EXPECT_NEAR(r3.metrics.accuracy_cm, 2.0, 0.05);
  EXPECT_DOUBLE_EQ(r3.metrics.comp_ratio_1cm, 0.0);

  EXPECT_EQ(table.rows[3].est_id, 0u);
  EXPECT_FALSE(table.rows[3].has_mesh);
  EXPECT_EQ(table.rows[3].note, "no match");

  EXPECT_EQ(table.num_with_mesh, 2);
  EXPECT_NEAR(table.mean.accuracy_cm, 0.5 * (r1.metrics.accuracy_cm + r3.metrics.accuracy_cm),
              1e-12);
  EXPECT_NEAR(table.mean.comp_ratio_1cm,
              0.5 * (r1.metrics.comp_ratio_1cm + r3.metrics.comp_ratio_1cm), 1e-12);
  EXPECT_EQ(table.mean.gt_points, r1.metrics.gt_points + r3.metrics.gt_points);

  const std::string text = format_recon_table(table);
  EXPECT_NE(text.find("(no mesh)"), std::string::npos) << text;
  EXPECT_NE(text.find("(no match)"), std::string::npos) << text;
  EXPECT_NE(text.find("41(cup)"), std::string::npos) << text;
  EXPECT_NE(text.find("over 2 of 4"), std::string::npos) << text;
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 6);  // header, 4 objects, mean
}

TEST(ObjectRecon, NoMeshesGivesAnEmptyMean) {
  const std::vector<GtObject> gt = {gt_sphere(1, 41, "cup", Eigen::Vector3d::Zero(), 0.1)};
  const ObjectReconTable table = evaluate_object_reconstructions(
      gt, {{5, 1}}, [](uint64_t) { return std::optional<TriangleMesh>(); }, {});
  EXPECT_EQ(table.num_with_mesh, 0);
  EXPECT_EQ(table.mean.accuracy_cm, 0.0);
  EXPECT_NE(format_recon_table(table).find("no object with a mesh"), std::string::npos);
}

TEST(ObjectRecon, MeshOutsideTheBoxIsReported) {
  const std::vector<GtObject> gt = {gt_sphere(1, 41, "cup", Eigen::Vector3d::Zero(), 0.1)};
  const ObjectReconTable table = evaluate_object_reconstructions(
      gt, {{5, 1}},
      [](uint64_t) -> std::optional<TriangleMesh> {
        return icosphere(Eigen::Vector3d(2, 0, 0), 0.1, 1);
      },
      {});
  ASSERT_EQ(table.rows.size(), 1u);
  EXPECT_FALSE(table.rows[0].has_mesh);
  EXPECT_NE(table.rows[0].note.find("cropped away"), std::string::npos) << table.rows[0].note;
}

}  // namespace
}  // namespace dqo::mesh
