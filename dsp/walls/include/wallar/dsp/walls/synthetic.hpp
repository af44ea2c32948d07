// SPDX-License-Identifier: Apache-2.0
/// @file synthetic.hpp
/// @brief Labelled synthetic scenes: the thesis's artificial scene (§4.1), a cluttered sparse
/// map with a small wall, and a box room. Deterministic for a seed.
///
/// Frames: camera-like, x right, y down, z forward; the viewpoint is the origin looking
/// along +z; gravity is +y ("down"). Noise is uniform across each surface (full width).
///
/// Threading: pure functions.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "wallar/core/plane.hpp"
#include "wallar/core/point_cloud.hpp"

namespace wallar::dsp {

enum class PointLabel : std::uint8_t {
  kWall,        //!< on the wall to find
  kFrontPlane,  //!< on the decoy plane in front of the wall
  kBacklier,    //!< behind the wall (mismatch, reflection, window)
  kOutlier,     //!< anywhere in front of the wall
  kFloor,
  kCeiling,
  kOtherWall,  //!< room scenes: the walls other than the first; sparse maps: the side wall
  kWindow,     //!< seen through a window in the wall: a patch of backliers
  kClutter,    //!< furniture in front of the wall (boxes)
};

/// "wall", "front_plane", "backlier", ... (for files and plots).
const char* label_name(PointLabel label);

struct LabelledCloud {
  PointCloud cloud;
  std::vector<PointLabel> labels;
  Plane wall;                    //!< ground truth of the wall to find (n toward the viewpoint)
  std::vector<Plane> surfaces;   //!< room scenes: every surface, in label order; sparse maps:
                                 //!< the wall, then the front plane and the side wall if any
  std::vector<Plane> all_walls;  //!< sparse maps: the walls to find (the wall, the side wall)
  Eigen::Vector3d down = Eigen::Vector3d::UnitY();  //!< gravity's direction in the cloud
};

/// §4.1: a wall_size x wall_size wall at wall_distance (normal along z); a plane_size square
/// plane at plane_distance with more points than the wall; backliers behind the wall with
/// probability rho_b (N_back = rho_b / (1 - rho_b) * N_wall); uniform outliers in front.
struct ThesisSceneParams {
  std::size_t wall_points = 100;
  std::size_t plane_points = 150;
  std::size_t outliers = 100;
  double rho_b = 0.3;
  double noise_m = 0.1;
  double wall_distance_m = 2.0;
  double wall_size_m = 4.0;
  double plane_distance_m = 1.0;
  double plane_size_m = 1.0;
  double backlier_depth_m = 1.0;  //!< backliers spread this far behind the wall
  /// What the thesis left open (§5): a window, i.e. points seen through a window_size_m square
  /// opening centred at (window_x_m, 0) on the wall, from 0.5 m to window_depth_m behind it
  /// (the wall's own points are kept: the window is a patch of backliers, not a hole).
  std::size_t window_points = 0;
  double window_size_m = 1.0;
  double window_x_m = 1.0;
  double window_depth_m = 3.0;
  /// Clutter: clutter_points on the visible faces (front, top, side) of clutter_objects
  /// 0.3-0.8 m boxes standing between the front plane and the wall.
  std::size_t clutter_points = 0;
  std::size_t clutter_objects = 4;
  std::uint64_t seed = 1;
};
/// Points are drawn in label order (wall, plane, backliers, outliers, window, clutter), so
/// adding windows or clutter leaves the rest of a seed's scene unchanged.
LabelledCloud make_thesis_scene(const ThesisSceneParams& p);

/// A sparse map as a tracker makes it: `points` in all, `wall_fraction` of them on a 4 x 3 m
/// wall at wall_distance, the rest clutter filling the room in front of it, plus backliers.
/// With the defaults of the variations below, the scenes of earlier versions, point for point.
struct SparseMapParams {
  std::size_t points = 2000;
  double wall_fraction = 0.035;
  double rho_b = 0.1;
  double noise_m = 0.02;
  double wall_distance_m = 3.0;
  std::uint64_t seed = 1;
  /// A cabinet: this many points on a 1 x 1 m front 0.6 m before the wall, its lower half,
  /// facing the viewer (labelled kFrontPlane; a true surface).
  std::size_t front_plane_points = 0;
  /// Clutter: 0 = uniform in the room in front of the wall; k = around k centres (Gaussian,
  /// sigma 0.15 m per axis), dense clumps of furniture.
  std::size_t clutter_clusters = 0;
  /// The whole scene pitched about x by this angle (a camera looking down): the points, the
  /// true planes and `down` turn together.
  double tilt_deg = 0.0;
  /// A second wall: this share of the points on the room's right side (x = +2 m, from 0.5 m to
  /// the wall, full height), meeting the wall in a corner (labelled kOtherWall).
  double side_wall_fraction = 0.0;
  /// The scene turned about the vertical (before the tilt) by this angle: negative turns the
  /// camera toward the right-hand corner, so that the side wall faces it.
  double yaw_deg = 0.0;
};
LabelledCloud make_sparse_map(const SparseMapParams& p);

/// One scene of the family the wall benchmark samples at random from `seed` (issue 22): 2,000
/// points, a wall of 2 - 10 % of them at 2.5 - 4.5 m (the clutter's density varies with the
/// room's depth), tilted 0 - 20 degrees, with a cabinet in front of the wall in half of the
/// scenes, clutter in clumps in half, and in half a second wall (2 - 10 %) in a corner with the
/// first, the camera turned 15 - 35 degrees toward it (else turned -20 - 20 degrees).
SparseMapParams sparse_map_family(std::uint64_t seed);

/// A box room (x in [-w/2, w/2], y from ceiling -h_up to floor +h_down, z in [-d/2, d/2])
/// around the viewpoint, with points on its 4 walls, floor and ceiling and clutter inside.
struct RoomSceneParams {
  double width_m = 6.0, depth_m = 5.0;
  double floor_below_m = 1.6, ceiling_above_m = 1.2;  //!< from the viewpoint
  std::size_t points_per_surface = 150;
  std::size_t clutter = 200;
  double noise_m = 0.02;
  std::uint64_t seed = 1;
};
LabelledCloud make_room_scene(const RoomSceneParams& p);

}  // namespace wallar::dsp
