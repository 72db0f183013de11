#include "dqo_map/tracking/params_yaml.h"

#include <string>

#include "dqo_map/config/yaml_schema.h"

namespace dqo::tracking {
namespace {

using config::Field;
using config::kInf;
using config::Section;

// One table describes every parameter: the shared reader and writer (config/yaml_schema.h) both
// walk it, so that a field added to the table is read and written alike.
Section schema(TrackingConfig& c) {
  TrackerParams& t = c.tracker;
  KeyframeSelectorParams& k = c.mapping_keyframes;
  StreamParams& st = c.stream;
  return Section{
      "",
      {},
      {
          Section{"tracker",
                  {
                      {"use_features", &t.use_features},
                      {"use_dense", &t.use_dense},
                      {"min_inliers_ok", &t.min_inliers_ok, 0, 100000},
                      {"frames_to_lost", &t.frames_to_lost, 1, 100000},
                      {"realign_dense", &t.realign_dense},
                  },
                  {
                      Section{"orb",
                              {
                                  {"num_features", &t.orb.num_features, 1, 100000},
                                  {"scale_factor", &t.orb.scale_factor, 1.001, 4.0},
                                  {"num_levels", &t.orb.num_levels, 1, 32},
                                  {"fast_threshold", &t.orb.fast_threshold, 1, 255},
                                  {"min_fast_threshold", &t.orb.min_fast_threshold, 1, 255},
                                  {"grid_cell_px", &t.orb.grid_cell_px, 4, 10000},
                                  {"min_depth", &t.orb.min_depth, 0.0, kInf},
                                  {"max_depth", &t.orb.max_depth, 0.0, kInf},
                              },
                              {}},
                      Section{"dense",
                              {
                                  {"pyramid_levels", &t.dense.pyramid_levels, 1, 4},
                                  {"finest_level", &t.dense.finest_level, 0, 3},
                                  {"iterations", &t.dense.iterations, 0, 1000},
                                  {"max_depth", &t.dense.max_depth, 0.0, kInf},
                                  {"max_point_distance", &t.dense.max_point_distance, 0.0, kInf},
                                  {"max_normal_angle_deg", &t.dense.max_normal_angle_deg, 0.0, 180.0},
                                  {"colour_weight", &t.dense.colour_weight, 0.0, kInf},
                                  {"huber_delta", &t.dense.huber_delta, 0.0, kInf},
                                  {"depth_sigma_per_m2", &t.dense.depth_sigma_per_m2, 0.0, kInf},
                                  {"min_depth_sigma_m", &t.dense.min_depth_sigma_m, 0.0, kInf},
                                  {"intensity_sigma", &t.dense.intensity_sigma, 1e-9, kInf},
                                  {"huber_delta_intensity", &t.dense.huber_delta_intensity, 0.0, kInf},
                                  {"min_gradient", &t.dense.min_gradient, 0.0, kInf},
                                  {"min_inliers", &t.dense.min_inliers, 0, 100000000},
                                  {"min_inlier_ratio", &t.dense.min_inlier_ratio, 0.0, 1.0},
                                  {"max_update_m", &t.dense.max_update_m, 0.0, kInf},
                                  {"max_update_deg", &t.dense.max_update_deg, 0.0, 180.0},
                                  {"max_whitened_rms", &t.dense.max_whitened_rms, 0.0, kInf},
                                  {"convergence_px", &t.dense.convergence_px, 0.0, kInf},
                              },
                              {}},
                      Section{"pose",
                              {
                                  {"huber_reprojection_px", &t.pose.huber_reprojection_px, 0.0, kInf},
                                  {"huber_depth_m", &t.pose.huber_depth_m, 0.0, kInf},
                                  {"depth_sigma_per_m2", &t.pose.depth_sigma_per_m2, 0.0, kInf},
                                  {"rounds", &t.pose.rounds, 1, 100},
                                  {"dense_prior_weight", &t.pose.dense_prior_weight, 0.0, kInf},
                                  {"depth_sigma_min_m", &t.pose.depth_sigma_min_m, 0.0, kInf},
                                  {"iterations", &t.pose.iterations, 1, 1000},
                                  {"max_prior_chi2", &t.pose.max_prior_chi2, 0.0, kInf},
                                  {"max_depth_gap_s", &t.pose.max_depth_gap_s, 0.0, kInf},
                                  {"asynchronous_depth_sigma_per_m2", &t.pose.asynchronous_depth_sigma_per_m2, 0.0, kInf},
                              },
                              {}},
                      Section{"search",
                              {
                                  {"frame_radius_px", &t.search.frame_radius_px, 0.0, kInf},
                                  {"dense_radius_px", &t.search.dense_radius_px, 0.0, kInf},
                                  {"local_map_radius_px", &t.search.local_map_radius_px, 0.0, kInf},
                                  {"local_map_ratio", &t.search.local_map_ratio, 0.0, 1.0},
                                  {"local_map_keyframes", &t.search.local_map_keyframes, 1, 100000},
                                  {"min_matches", &t.search.min_matches, 0, 100000},
                              },
                              {}},
                      Section{"keyframes",
                              {
                                  {"min_frames", &t.keyframes.min_frames, 0, 100000},
                                  {"max_frames", &t.keyframes.max_frames, 1, 100000},
                                  {"min_tracked_ratio", &t.keyframes.min_tracked_ratio, 0.0, 1.0},
                                  {"min_close_points", &t.keyframes.min_close_points, 0, 100000},
                                  {"weak_translation_m", &t.keyframes.weak_translation_m, 0.0, kInf},
                                  {"weak_rotation_deg", &t.keyframes.weak_rotation_deg, 0.0, 180.0},
                                  {"max_new_points", &t.keyframes.max_new_points, 0, 1000000},
                                  {"far_translation_m", &t.keyframes.far_translation_m, 0.0, kInf},
                                  {"far_rotation_deg", &t.keyframes.far_rotation_deg, 0.0, 180.0},
                              },
                              {}},
                      Section{"local_ba",
                              {
                                  {"enabled", &t.local_ba.enabled},
                                  {"covisible_keyframes", &t.local_ba.covisible_keyframes, 1, 1000},
                                  {"iterations", &t.local_ba.iterations, 1, 1000},
                                  {"fixed_keyframes", &t.local_ba.fixed_keyframes, 0, 1000},
                                  {"synchronous", &t.local_ba.synchronous},
                                  {"apply_after_frames", &t.local_ba.apply_after_frames, 1, 1000},
                                  {"deterministic", &t.local_ba.deterministic},
                              },
                              {}},
                      Section{"loop",
                              {
                                  {"enabled", &t.loop.enabled},
                                  {"min_keyframe_gap", &t.loop.min_keyframe_gap, 1, 100000},
                                  {"min_matches", &t.loop.min_matches, 4, 100000},
                                  {"sample_descriptors", &t.loop.sample_descriptors, 0, 100000},
                                  {"max_verify", &t.loop.max_verify, 1, 1000},
                                  {"min_inliers", &t.loop.min_inliers, 4, 100000},
                                  {"pose_graph_iterations", &t.loop.pose_graph_iterations, 1, 10000},
                                  {"min_edge_shared", &t.loop.min_edge_shared, 1, 100000},
                                  {"global_ba", &t.loop.global_ba},
                                  {"global_ba_iterations", &t.loop.global_ba_iterations, 1, 10000},
                                  {"final_global_ba", &t.loop.final_global_ba},
                              },
                              {}},
                      Section{"rolling_shutter",
                              {
                                  {"readout_s", &t.rolling_shutter.readout_s, 0.0, 1.0},
                                  {"max_step_s", &t.rolling_shutter.max_step_s, 0.0, kInf},
                              },
                              {}},
                      Section{"refine",
                              {
                                  {"enabled", &t.refine.enabled},
                                  {"reregister", &t.refine.reregister},
                                  {"full_ba", &t.refine.full_ba},
                                  {"sigma_m", &t.refine.sigma_m, 1e-6, kInf},
                                  {"sigma_deg", &t.refine.sigma_deg, 1e-6, 180.0},
                                  {"degraded_sigma_scale", &t.refine.degraded_sigma_scale, 1.0, kInf},
                                  {"acceleration_sigma", &t.refine.acceleration_sigma, 1e-6, kInf},
                                  {"angular_acceleration_sigma_deg", &t.refine.angular_acceleration_sigma_deg, 1e-6, kInf},
                                  {"max_gap_s", &t.refine.max_gap_s, 0.0, kInf},
                                  {"iterations", &t.refine.iterations, 1, 10000},
                              },
                              {}},
                      Section{"quality",
                              {
                                  {"ok_inliers", &t.quality.ok_inliers, 0, 100000},
                                  {"ok_depth_inliers", &t.quality.ok_depth_inliers, 0, 100000},
                                  {"min_spread", &t.quality.min_spread, 0.0, 1.0},
                                  {"dense_max_rms", &t.quality.dense_max_rms, 0.0, kInf},
                                  {"dense_min_inlier_ratio", &t.quality.dense_min_inlier_ratio, 0.0, 1.0},
                                  {"max_disagreement_m", &t.quality.max_disagreement_m, 0.0, kInf},
                                  {"max_disagreement_deg", &t.quality.max_disagreement_deg, 0.0, 180.0},
                                  {"confirm_features", &t.quality.confirm_features},
                                  {"confirm_window_frames", &t.quality.confirm_window_frames, 0, 1000},
                                  {"confirm_max_rms", &t.quality.confirm_max_rms, 0.0, kInf},
                                  {"confirm_max_disagreement_m", &t.quality.confirm_max_disagreement_m, 0.0, kInf},
                                  {"confirm_max_disagreement_deg", &t.quality.confirm_max_disagreement_deg, 0.0, 180.0},
                              },
                              {}},
                      Section{"object_landmarks",
                              {
                                  {"enabled", &t.objects.enabled},
                                  {"box_sigma_px", &t.objects.box_sigma_px, 0.0, kInf},
                                  {"huber", &t.objects.huber, 0.0, kInf},
                                  {"min_confidence", &t.objects.min_confidence, 0.0, 1.0},
                                  {"min_observations", &t.objects.min_observations, 0, 1000000},
                                  {"border_px", &t.objects.border_px, 0.0, kInf},
                                  {"min_iou", &t.objects.min_iou, 0.0, 1.0},
                              },
                              {}},
                      Section{"reloc",
                              {
                                  {"candidate_keyframes", &t.reloc.candidate_keyframes, 1, 10000},
                                  {"min_inliers", &t.reloc.min_inliers, 3, 100000},
                                  {"max_pnp", &t.reloc.max_pnp, 1, 1000},
                              },
                              {}},
                  }},
          Section{"mapping_keyframes",
                  {
                      {"max_rotation_deg", &k.max_rotation_deg, 0.0, 360.0},
                      {"max_translation_m", &k.max_translation_m, 0.0, kInf},
                      {"max_frames", &k.max_frames, -1, 1000000},
                  },
                  {}},
          Section{"stream",
                  {
                      {"out_of_order_s", &st.out_of_order_s, 0.0, kInf},
                  },
                  {}},
      }};
}

}  // namespace

std::optional<TrackingConfig> parse_tracking_config(const std::string& text, const std::string& source,
                                                    std::string* error, const TrackingConfig& base,
                                                    bool positions) {
  TrackingConfig config = base;
  if (!config::read_yaml(text, source, positions, schema(config), error)) return std::nullopt;
  if (config.tracker.dense.finest_level >= config.tracker.dense.pyramid_levels) {
    if (error) {
      *error = source + ": tracker.dense.finest_level (" + std::to_string(config.tracker.dense.finest_level) +
               ") must be below tracker.dense.pyramid_levels (" +
               std::to_string(config.tracker.dense.pyramid_levels) + ")";
    }
    return std::nullopt;
  }
  if (config.tracker.orb.min_depth >= config.tracker.orb.max_depth) {
    if (error) *error = source + ": tracker.orb.min_depth must be below tracker.orb.max_depth";
    return std::nullopt;
  }
  if (!config.tracker.use_features && !config.tracker.use_dense) {
    if (error) *error = source + ": tracker.use_features and tracker.use_dense are both false";
    return std::nullopt;
  }
  return config;
}

std::optional<TrackingConfig> load_tracking_config(const std::string& path, std::string* error) {
  std::string text;
  if (!config::read_text_file(path, &text, error)) return std::nullopt;
  return parse_tracking_config(text, path, error);
}

std::string tracking_config_to_yaml(const TrackingConfig& config) {
  TrackingConfig copy = config;  // the schema points into a mutable config
  return config::write_yaml(schema(copy));
}

}  // namespace dqo::tracking
