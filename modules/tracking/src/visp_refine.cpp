#include "visp_refine.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include <visp3/core/vpException.h>
#include <visp3/vision/vpHomography.h>
#include <visp3/core/vpImage.h>
#include <visp3/core/vpImagePoint.h>
#include <visp3/tt/vpTemplateTrackerSSDInverseCompositional.h>
#include <visp3/tt/vpTemplateTrackerWarpHomography.h>
#include <visp3/tt/vpTemplateTrackerWarpSRT.h>
#include <visp3/tt/vpTemplateTrackerWarpTranslation.h>
#include <visp3/tt/vpTemplateTrackerZNCCInverseCompositional.h>

namespace mosaicloc::tracking::detail {
namespace {

void ToVisp(const cv::Mat& image, vpImage<unsigned char>* out) {
  out->resize(static_cast<unsigned>(image.rows), static_cast<unsigned>(image.cols));
  for (int y = 0; y < image.rows; ++y) {
    std::copy_n(image.ptr<unsigned char>(y), image.cols, (*out)[static_cast<unsigned>(y)]);
  }
}

}  // namespace

// ViSP's template trackers, used the way they work reliably:
// - the template image is a small crop around the template, because initialisation scans
//   the whole reference image;
// - the zone is two explicit triangles (4 points without Delaunay give a broken triangle);
// - the current image is a small window around the predicted place, so ViSP's Gaussian
//   blur (which track() applies to the whole current image) stays cheap, and it is needed:
//   without it the trackers stall on floors with pixel-scale detail;
// - equal sampling in both directions (unequal sampling crashes), a pyramid only when asked;
// - exceptions (the template leaving the image) become a failed answer;
// - the warp is read back through warpX, so no parameter layout is assumed.
VispAnswer TrackWithVisp(const cv::Mat& templ_image, const cv::Mat& window, const VispRequest& request) {
  VispAnswer answer;
  vpImage<unsigned char> templ, current;
  ToVisp(templ_image, &templ);
  ToVisp(window, &current);

  std::unique_ptr<vpTemplateTrackerWarp> warp;
  switch (request.warp) {
    case VispWarp::kTranslation: warp.reset(new vpTemplateTrackerWarpTranslation()); break;
    case VispWarp::kSrt: warp.reset(new vpTemplateTrackerWarpSRT()); break;
    case VispWarp::kHomography: warp.reset(new vpTemplateTrackerWarpHomography()); break;
  }
  std::unique_ptr<vpTemplateTracker> tracker;
  if (request.ssd) {
    tracker.reset(new vpTemplateTrackerSSDInverseCompositional(warp.get()));
  } else {
    tracker.reset(new vpTemplateTrackerZNCCInverseCompositional(warp.get()));
  }
  tracker->setBlur(true);
  tracker->setSampling(request.sampling, request.sampling);
  tracker->setIterationMax(static_cast<unsigned>(request.max_iterations));
  if (request.pyramid_levels > 1) tracker->setPyramidal(static_cast<unsigned>(request.pyramid_levels), 0);

  // vpImagePoint is (i = row, j = column).
  const double i0 = request.zone.y, j0 = request.zone.x;
  const double i1 = i0 + request.zone.height - 1, j1 = j0 + request.zone.width - 1;
  const std::vector<vpImagePoint> zone = {vpImagePoint(i0, j0), vpImagePoint(i0, j1), vpImagePoint(i1, j1),
                                          vpImagePoint(i0, j0), vpImagePoint(i1, j1), vpImagePoint(i1, j0)};
  try {
    tracker->initFromPoints(templ, zone, false);
    vpColVector p(warp->getNbParam(), 0.0);
    if (request.warp == VispWarp::kHomography) {
      vpHomography h;
      h[0][2] = request.start_u;
      h[1][2] = request.start_v;
      static_cast<vpTemplateTrackerWarpHomography*>(warp.get())->getParam(h, p);
    } else {
      p[p.size() - 2] = request.start_u;
      p[p.size() - 1] = request.start_v;
    }
    tracker->setp(p);
    tracker->track(current);
    p = tracker->getp();
    answer.iterations = static_cast<int>(tracker->getNbIteration());
    vpColVector from(2), to(2);
    from[0] = j0 + 0.5 * (request.zone.width - 1);
    from[1] = i0 + 0.5 * (request.zone.height - 1);
    warp->warpX(from, to, p);
    answer.centre_u = to[0];
    answer.centre_v = to[1];
    vpColVector along(2), along_to(2);
    along[0] = from[0] + 0.5 * request.zone.width;
    along[1] = from[1];
    warp->warpX(along, along_to, p);
    answer.rotation_rad = std::atan2(along_to[1] - to[1], along_to[0] - to[0]);
    answer.diverged = tracker->getDiverge() || !std::isfinite(to[0]) || !std::isfinite(to[1]);
    answer.ok = !answer.diverged;
    if (answer.diverged) answer.message = "ViSP tracker diverged";
  } catch (const vpException& e) {
    answer.message = e.getMessage();
  } catch (const std::exception& e) {
    answer.message = e.what();
  }
  return answer;
}

}  // namespace mosaicloc::tracking::detail
