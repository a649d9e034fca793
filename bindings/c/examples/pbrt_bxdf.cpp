// pbrt_bxdf.cpp: a neural material with a learned sampler in the shape of a pbrt-v4 BxDF
// (`f`, `Sample_f`, `PDF`), written against the C ABI. pbrt's names: `wo` is the direction
// towards the camera (neusample's `wi`, the one the sampler is conditioned on) and the
// sampled `wi` is neusample's `wo`. Everything is in the local shading frame.
//
// Build (from the repository root, after `cargo build -p neusample-capi`):
//   c++ -std=c++17 -Wall -Wextra -O2 -Ibindings/c/include bindings/c/examples/pbrt_bxdf.cpp
//       target/debug/libneusample_capi.a -lm -lpthread -ldl -o target/pbrt_bxdf   (one line)
//   target/pbrt_bxdf fixtures
#include "neusample.h"

#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

namespace {

struct Vector3f {
  float x, y, z;
};
struct Point2f {
  float x, y;
};
struct RGB {
  float r, g, b;
};
struct BSDFSample {
  RGB f;
  Vector3f wi;
  float pdf;
};

NsVec3 ToNs(Vector3f v) { return {v.x, v.y, v.z}; }

void Check(NsStatus s, const char *what) {
  if (s != NS_OK) throw std::runtime_error(std::string(what) + ": " + ns_status_name(s) + " " + ns_last_error());
}

// Owning wrappers for the handles.
struct BlobDel { void operator()(NsBlob *p) const { ns_blob_free(p); } };
struct SamplerDel { void operator()(NsSampler *p) const { ns_sampler_free(p); } };
struct MaterialDel { void operator()(NsMaterial *p) const { ns_material_free(p); } };
struct PreparedDel { void operator()(NsPrepared *p) const { ns_prepared_free(p); } };
using Sampler = std::unique_ptr<NsSampler, SamplerDel>;
using Material = std::unique_ptr<NsMaterial, MaterialDel>;
using Prepared = std::unique_ptr<NsPrepared, PreparedDel>;

std::unique_ptr<NsBlob, BlobDel> OpenBlob(const std::string &path) {
  NsBlob *b = nullptr;
  Check(ns_blob_open(path.c_str(), &b), path.c_str());
  return std::unique_ptr<NsBlob, BlobDel>(b);
}

// The BxDF of one shading point: φ from the texture at uv; the sampler prepared for pbrt's
// `wo` by one helper that both Sample_f and PDF call, so they cannot disagree. pbrt's
// integrators weigh a sample by f·cos/pdf and use the same pdf for MIS; a sample carries
// both the density it was drawn with (pdf, q) and its MIS density (mis_pdf, PDF's value at
// its direction), which differ for the reparameterization sampler only. Sample_f returns
// mis_pdf and scales f by mis_pdf/q, so that f·cos/pdf is still the sample's exact weight
// f·cos/q.
class NeuralBxDF {
 public:
  NeuralBxDF(const NsMaterial *material, const NsSampler *sampler, NsPrepared *scratch,
             Point2f uv)
      : material_(material), sampler_(sampler), scratch_(scratch) {
    Check(ns_material_features(material_, {uv.x, uv.y}, &phi_), "features");
  }

  // BRDF value (no cosine).
  RGB f(Vector3f wo, Vector3f wi) const {
    NsRgb c{};
    Check(ns_material_eval(material_, &phi_, ToNs(wo), ToNs(wi), &c), "eval");
    return {c.r, c.g, c.b};
  }

  std::optional<BSDFSample> Sample_f(Vector3f wo, float /*uc*/, Point2f u) const {
    if (!Prepare(wo)) return std::nullopt;
    NsSample s{};
    NsStatus st = ns_prepared_sample(sampler_, scratch_, {u.x, u.y}, &s);
    if (st == NS_REFUSED) return std::nullopt;
    Check(st, "sample");
    Vector3f wi{s.wo.x, s.wo.y, s.wo.z};
    RGB value = f(wo, wi);
    if (!(s.mis_pdf > 0.0f)) return std::nullopt;
    float k = s.mis_pdf / s.pdf;
    return BSDFSample{{value.r * k, value.g * k, value.b * k}, wi, s.mis_pdf};
  }

  float PDF(Vector3f wo, Vector3f wi) const {
    if (!Prepare(wo)) return 0.0f;
    float pdf = 0.0f;
    Check(ns_prepared_pdf(sampler_, scratch_, ToNs(wi), &pdf), "pdf");
    return pdf;
  }

 private:
  // Runs the sampler's networks for (φ, wo) unless the scratch state already holds them.
  bool Prepare(Vector3f wo) const {
    if (prepared_ && wo.x == wo_.x && wo.y == wo_.y && wo.z == wo_.z) return ok_;
    NsStatus st = ns_prepare(sampler_, &phi_, ToNs(wo), scratch_);
    if (st != NS_OK && st != NS_REFUSED) Check(st, "prepare");
    prepared_ = true;
    wo_ = wo;
    ok_ = st == NS_OK;
    return ok_;
  }

  const NsMaterial *material_;
  const NsSampler *sampler_;
  NsPrepared *scratch_;
  NsPhi phi_{};
  mutable bool prepared_ = false, ok_ = false;
  mutable Vector3f wo_{};
};

}  // namespace

int main(int argc, char **argv) {
  const std::string root = argc > 1 ? argv[1] : "fixtures";
  int failures = 0, checks = 0;
  try {
    NsMaterial *m = nullptr;
    Check(ns_material_new(OpenBlob(root + "/materials/neural/goat_leather_neural.nsb").get(), &m),
          "material");
    Material material(m);
    for (const char *method : {"flow", "histogram-mixture", "reparam"}) {
      NsSampler *s = nullptr;
      Check(ns_sampler_new(OpenBlob(root + "/blobs/goat_leather_neural/" + method + ".nsb").get(), &s),
            method);
      Sampler sampler(s);
      NsPrepared *p = nullptr;
      Check(ns_prepared_new(&p), "prepared");
      Prepared scratch(p);
      // Albedo estimate ∫ f cos dω by BSDF sampling, and Sample_f's pdf against PDF.
      int method_checks = 0;
      NeuralBxDF bxdf(material.get(), sampler.get(), scratch.get(), {0.3f, 0.6f});
      Vector3f wo{0.36f, -0.48f, 0.8f};
      const int n = 64;
      double albedo = 0.0;
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          Point2f u{(i + 0.5f) / n, (j + 0.5f) / n};
          auto bs = bxdf.Sample_f(wo, 0.5f, u);
          if (!bs) continue;
          ++checks;
          ++method_checks;
          float pdf = bxdf.PDF(wo, bs->wi);
          if (pdf != bs->pdf) {
            ++failures;
            std::fprintf(stderr, "FAIL %s: PDF %.9g != Sample_f pdf %.9g\n", method, pdf, bs->pdf);
          }
          albedo += bs->f.g * bs->wi.z / bs->pdf;
        }
      }
      std::printf("pbrt-shaped BxDF, goat leather, %-17s: Sample_f pdf == PDF on %d samples, "
                  "albedo (green) ≈ %.4f\n",
                  method, method_checks, albedo / (n * n));
    }
  } catch (const std::exception &e) {
    std::fprintf(stderr, "FAIL: %s\n", e.what());
    return 1;
  }
  std::printf("%d passed, %d failed\n", checks - failures, failures);
  return failures == 0 ? 0 : 1;
}
