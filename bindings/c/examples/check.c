/*
 * check.c: loads the fixture blobs through the C ABI and checks, for every sampler of the
 * three demo materials (and the cosine sampler):
 *   - a sample's pdf equals ns_pdf at the sampled direction (bit for bit),
 *   - the prepared path (ns_prepare + ns_prepared_sample/pdf) and the batched calls equal
 *     the scalar calls within the batched runtime's tolerances (5e-4 relative on a pdf, 1e-3
 *     on a direction), and inside each a sample's pdf is the pdf at the sampled direction
 *     bit for bit,
 *   - bad input gives the documented status, never a crash: a missing file, a corrupted
 *     blob, a material blob used as a sampler, NULL handles, NaN directions, n = 0,
 *     overlapping output arrays,
 *   - the measured-material calls' error paths (NULL, a sampler blob given as measured),
 *   - the mint's RGL file opened with ns_measured_open_bsdf: eval finite and >= 0, a sample's
 *     pdf equals ns_measured_pdf at its direction (1e-3 relative), its weight is
 *     f cos(theta_o) / pdf within 1e-4 of its largest channel (the weight comes from the
 *     sample's own table coordinates, f from the VNDF's inversion at the sampled direction,
 *     which loses digits where the tables are steep), the batched calls equal the scalar ones
 *     bit for bit on 64 lanes, and a truncated copy, a missing file and NULL are refused with
 *     their status.
 *
 * Build (from the repository root, after `cargo build -p neusample-capi`):
 *   cc -std=c99 -Wall -Wextra -O2 -Ibindings/c/include bindings/c/examples/check.c
 *      target/debug/libneusample_capi.a -lm -lpthread -ldl -o target/check_c   (one line)
 *   target/check_c fixtures
 */
#include "neusample.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures = 0;
static int checks = 0;

#define CHECK(cond, ...)                                 \
  do {                                                   \
    ++checks;                                            \
    if (!(cond)) {                                       \
      ++failures;                                        \
      fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__); \
      fprintf(stderr, __VA_ARGS__);                      \
      fprintf(stderr, "\n");                             \
    }                                                    \
  } while (0)

#define EXPECT_STATUS(call, want)                                                     \
  do {                                                                              \
    NsStatus got_ = (call);                                                         \
    CHECK(got_ == (want), "%s returned %s (%s), expected %s", #call,                 \
          ns_status_name(got_), ns_last_error(), ns_status_name(want));             \
  } while (0)

static const char *MATERIALS[] = {"goat_leather_neural", "brushed_metal_neural",
                                  "victorian_fabric_neural"};
static const char *METHODS[] = {"baseline",         "analytic",          "flow",
                                "affine-flow",      "disk-flow",         "direct-histogram",
                                "histogram-mixture", "reparam"};

/* A small deterministic generator (xorshift32) for u in [0, 1). */
static unsigned rng_state = 0x9e3779b9u;
static float next_u(void) {
  rng_state ^= rng_state << 13;
  rng_state ^= rng_state >> 17;
  rng_state ^= rng_state << 5;
  return (float)(rng_state >> 8) * (1.0f / 16777216.0f);
}

static NsVec3 normalize(float x, float y, float z) {
  float l = sqrtf(x * x + y * y + z * z);
  NsVec3 v = {x / l, y / l, z / l};
  return v;
}

enum { LANES = 37 };

/* The batched runtime (and the prepared path, which runs it on one lane) agrees with the
 * scalar calls within its tolerances: 5e-4 relative on a pdf at the same direction, 1e-3 on
 * a sampled direction. (Near the rim a sample's solid-angle pdf moves with its direction
 * more than that: compare pdfs at one direction.) */
static int close_pdfs(float a, float b) { return fabsf(a - b) <= 5e-4f * fmaxf(a, b); }

static int close_samples(const NsSample *a, const NsSample *b) {
  float d = fmaxf(fabsf(a->wo.x - b->wo.x),
                  fmaxf(fabsf(a->wo.y - b->wo.y), fabsf(a->wo.z - b->wo.z)));
  return (a->pdf > 0.0f) == (b->pdf > 0.0f) && (a->mis_pdf > 0.0f) == (b->mis_pdf > 0.0f) &&
         d <= 1e-3f;
}

/* Checks one sampler against one material at a few shading points. */
static void check_sampler(const char *label, const NsSampler *s, const NsMaterial *m) {
  const NsVec3 wis[3] = {normalize(0.0f, 0.0f, 1.0f), normalize(0.5f, -0.3f, 0.8f),
                         normalize(-0.9f, 0.2f, 0.25f)};
  const NsVec2 uvs[2] = {{0.25f, 0.5f}, {0.77f, 0.13f}};
  NsPrepared *prep = NULL;
  EXPECT_STATUS(ns_prepared_new(&prep), NS_OK);
  int samples = 0, refused = 0;
  for (int a = 0; a < 2; ++a) {
    NsPhi phi;
    EXPECT_STATUS(ns_material_features(m, uvs[a], &phi), NS_OK);
    for (int b = 0; b < 3; ++b) {
      NsVec3 wi = wis[b];
      EXPECT_STATUS(ns_prepare(s, &phi, wi, prep), NS_OK);
      /* Scalar: sample and pdf agree; the prepared path equals the fused calls. */
      float lane_u[2][LANES];
      NsSample scalar[LANES];
      for (int i = 0; i < LANES; ++i) {
        NsVec2 u = {next_u(), next_u()};
        lane_u[0][i] = u.x;
        lane_u[1][i] = u.y;
        NsSample smp, smp2;
        NsStatus st = ns_sample(s, &phi, wi, u, &smp);
        CHECK(st == NS_OK || st == NS_REFUSED, "%s: ns_sample -> %s", label, ns_status_name(st));
        NsStatus st2 = ns_prepared_sample(s, prep, u, &smp2);
        CHECK(st2 == st && close_samples(&smp, &smp2),
              "%s: prepared sample differs from fused sample", label);
        if (st2 == NS_OK) {
          float p3 = -1.0f, p4 = -1.0f;
          EXPECT_STATUS(ns_prepared_pdf(s, prep, smp2.wo, &p3), NS_OK);
          CHECK(p3 == smp2.mis_pdf,
                "%s: prepared pdf(sample.wo) = %.9g but sample.mis_pdf = %.9g", label, p3,
                smp2.mis_pdf);
          EXPECT_STATUS(ns_pdf(s, &phi, wi, smp2.wo, &p4), NS_OK);
          CHECK(close_pdfs(p4, p3), "%s: prepared pdf %.9g != fused pdf %.9g", label, p3, p4);
        }
        scalar[i] = smp;
        if (st != NS_OK) {
          ++refused;
          CHECK(smp.pdf == 0.0f && smp.mis_pdf == 0.0f && smp.wo.z == 0.0f,
                "%s: refused sample not zeroed", label);
          continue;
        }
        ++samples;
        CHECK(smp.pdf > 0.0f && isfinite(smp.pdf) && smp.wo.z > 0.0f,
              "%s: bad sample pdf %g wo.z %g", label, smp.pdf, smp.wo.z);
        float p = -1.0f, p2 = -1.0f;
        EXPECT_STATUS(ns_pdf(s, &phi, wi, smp.wo, &p), NS_OK);
        EXPECT_STATUS(ns_prepared_pdf(s, prep, smp.wo, &p2), NS_OK);
        /* Every kind's MIS density is its pdf at the sample; the density the sample was
         * drawn with is that too except for the reparameterization sampler's warp. */
        CHECK(p == smp.mis_pdf, "%s: pdf(sample.wo) = %.9g but sample.mis_pdf = %.9g", label,
              p, smp.mis_pdf);
        CHECK(smp.pdf == smp.mis_pdf || strcmp(label, "reparam") == 0,
              "%s: sample.pdf %.9g != sample.mis_pdf %.9g", label, smp.pdf, smp.mis_pdf);
        CHECK(close_pdfs(p2, p), "%s: prepared pdf %.9g != fused pdf %.9g", label, p2, p);
        NsRgb f;
        EXPECT_STATUS(ns_material_eval(m, &phi, wi, smp.wo, &f), NS_OK);
        CHECK(f.r > 0.0f && f.g > 0.0f && f.b > 0.0f, "%s: f not positive", label);
      }
      /* Batched = scalar, lane by lane. */
      float phi_rows[NS_FEATURE_DIM][LANES], wi_rows[3][LANES];
      float wo_rows[3][LANES], pdf[LANES], mis[LANES], pdf_again[LANES];
      for (int i = 0; i < LANES; ++i) {
        for (int k = 0; k < NS_FEATURE_DIM; ++k) phi_rows[k][i] = phi.v[k];
        wi_rows[0][i] = wi.x;
        wi_rows[1][i] = wi.y;
        wi_rows[2][i] = wi.z;
      }
      NsFeatures fphi = ns_features_rows(&phi_rows[0][0], LANES);
      NsVec3s vwi = ns_vec3s_rows(&wi_rows[0][0], LANES);
      EXPECT_STATUS(ns_sample_batch(s, LANES, fphi, vwi, ns_vec2s_rows(&lane_u[0][0], LANES),
                                    ns_samples_mut_rows(&wo_rows[0][0], pdf, mis, LANES)),
                    NS_OK);
      for (int i = 0; i < LANES; ++i) {
        NsSample b = {{wo_rows[0][i], wo_rows[1][i], wo_rows[2][i]}, pdf[i], mis[i]};
        CHECK(close_samples(&b, &scalar[i]),
              "%s: batched sample lane %d at %.9g %.9g, scalar at %.9g %.9g", label, i, b.wo.x,
              b.wo.y, scalar[i].wo.x, scalar[i].wo.y);
        if (b.pdf > 0.0f) {
          float p = -1.0f;
          EXPECT_STATUS(ns_pdf(s, &phi, wi, b.wo, &p), NS_OK);
          CHECK(close_pdfs(b.mis_pdf, p),
                "%s: batched sample lane %d: mis_pdf %.9g, scalar pdf %.9g", label, i,
                b.mis_pdf, p);
          CHECK(close_pdfs(b.pdf, scalar[i].pdf),
                "%s: batched sample lane %d: pdf %.9g, scalar sample's %.9g", label, i, b.pdf,
                scalar[i].pdf);
        }
      }
      EXPECT_STATUS(
          ns_pdf_batch(s, LANES, fphi, vwi, ns_vec3s_rows(&wo_rows[0][0], LANES), pdf_again),
          NS_OK);
      for (int i = 0; i < LANES; ++i) {
        CHECK(pdf_again[i] == mis[i], "%s: batched pdf lane %d = %.9g, sample's mis_pdf %.9g",
              label, i, pdf_again[i], mis[i]);
      }
    }
  }
  printf("  %-44s %4d samples, %3d refused: sample/pdf agree, batched = scalar within tolerance\n", label,
         samples, refused);
  ns_prepared_free(prep);
}

static void check_bad_input(const char *root, const NsMaterial *m, const NsSampler *s) {
  char path[1024];
  NsBlob *blob = NULL;
  /* A missing file. */
  snprintf(path, sizeof path, "%s/blobs/no_such_material/flow.nsb", root);
  EXPECT_STATUS(ns_blob_open(path, &blob), NS_ERR_IO);
  CHECK(blob == NULL, "handle written on error");
  CHECK(strstr(ns_last_error(), "no_such_material") != NULL, "message names the file: %s",
        ns_last_error());
  /* A corrupted blob: one flipped bit. */
  snprintf(path, sizeof path, "%s/blobs/goat_leather_neural/analytic.nsb", root);
  FILE *fp = fopen(path, "rb");
  CHECK(fp != NULL, "cannot open %s", path);
  if (fp) {
    unsigned char buf[1 << 16];
    size_t len = fread(buf, 1, sizeof buf, fp);
    fclose(fp);
    EXPECT_STATUS(ns_blob_from_bytes(buf, len, &blob), NS_OK);
    ns_blob_free(blob);
    blob = NULL;
    buf[len / 2] ^= 0x10;
    EXPECT_STATUS(ns_blob_from_bytes(buf, len, &blob), NS_ERR_CHECKSUM_MISMATCH);
    EXPECT_STATUS(ns_blob_from_bytes(buf, 7, &blob), NS_ERR_TRUNCATED);
    EXPECT_STATUS(ns_blob_from_bytes((const uint8_t *)"garbage!garbage!", 16, &blob),
                  NS_ERR_BAD_MAGIC);
    EXPECT_STATUS(ns_blob_from_bytes(NULL, 0, &blob), NS_ERR_TRUNCATED);
    CHECK(blob == NULL, "handle written on error");
  }
  /* A material blob is not a sampler, a sampler blob is not a material. */
  snprintf(path, sizeof path, "%s/materials/neural/goat_leather_neural.nsb", root);
  EXPECT_STATUS(ns_blob_open(path, &blob), NS_OK);
  NsSampler *bad = NULL;
  EXPECT_STATUS(ns_sampler_new(blob, &bad), NS_ERR_NOT_A_SAMPLER);
  ns_blob_free(blob);
  snprintf(path, sizeof path, "%s/blobs/goat_leather_neural/flow.nsb", root);
  EXPECT_STATUS(ns_blob_open(path, &blob), NS_OK);
  NsMaterial *badm = NULL;
  EXPECT_STATUS(ns_material_new(blob, &badm), NS_ERR_WRONG_KIND);
  ns_blob_free(blob);
  /* NULL handles and outputs. */
  NsPhi phi;
  NsSample smp;
  float p;
  NsVec3 up = {0.0f, 0.0f, 1.0f};
  NsVec2 u = {0.5f, 0.5f};
  EXPECT_STATUS(ns_blob_open(NULL, &blob), NS_ERR_NULL_POINTER);
  EXPECT_STATUS(ns_blob_open(path, NULL), NS_ERR_NULL_POINTER);
  EXPECT_STATUS(ns_material_features(NULL, u, &phi), NS_ERR_NULL_POINTER);
  EXPECT_STATUS(ns_material_features(m, u, &phi), NS_OK);
  EXPECT_STATUS(ns_sample(NULL, &phi, up, u, &smp), NS_ERR_NULL_POINTER);
  EXPECT_STATUS(ns_sample(s, NULL, up, u, &smp), NS_ERR_NULL_POINTER);
  EXPECT_STATUS(ns_pdf(s, &phi, up, up, NULL), NS_ERR_NULL_POINTER);
  /* NaN directions: scalar calls say so; batched lanes are refused (zeros), others intact. */
  NsVec3 nan_dir = {NAN, 0.0f, 1.0f};
  EXPECT_STATUS(ns_sample(s, &phi, nan_dir, u, &smp), NS_ERR_NOT_FINITE);
  CHECK(smp.pdf == 0.0f, "output not zeroed");
  EXPECT_STATUS(ns_pdf(s, &phi, up, nan_dir, &p), NS_ERR_NOT_FINITE);
  NsVec3 below = {0.0f, 0.6f, -0.8f};
  EXPECT_STATUS(ns_sample(s, &phi, below, u, &smp), NS_REFUSED);
  EXPECT_STATUS(ns_pdf(s, &phi, up, below, &p), NS_OK);
  CHECK(p == 0.0f, "pdf below the horizon = %g", p);
  {
    float phis[NS_FEATURE_DIM][2], wis[3][2] = {{NAN, 0.0f}, {0.0f, 0.0f}, {1.0f, 1.0f}};
    float us[2][2] = {{0.3f, 0.3f}, {0.6f, 0.6f}}, wos[3][2], pdfs[2], mises[2];
    for (int k = 0; k < NS_FEATURE_DIM; ++k) phis[k][0] = phis[k][1] = phi.v[k];
    EXPECT_STATUS(ns_sample_batch(s, 2, ns_features_rows(&phis[0][0], 2),
                                  ns_vec3s_rows(&wis[0][0], 2), ns_vec2s_rows(&us[0][0], 2),
                                  ns_samples_mut_rows(&wos[0][0], pdfs, mises, 2)),
                  NS_OK);
    CHECK(pdfs[0] == 0.0f && mises[0] == 0.0f && wos[2][0] == 0.0f, "NaN lane not refused");
    CHECK(pdfs[1] > 0.0f, "a NaN lane disturbed its neighbour");
    /* Outputs overlapping an input or each other. */
    EXPECT_STATUS(ns_sample_batch(s, 2, ns_features_rows(&phis[0][0], 2),
                                  ns_vec3s_rows(&wis[0][0], 2), ns_vec2s_rows(&us[0][0], 2),
                                  ns_samples_mut_rows(&wis[0][0], pdfs, mises, 2)),
                  NS_ERR_INVALID_ARGUMENT);
    EXPECT_STATUS(ns_pdf_batch(s, 2, ns_features_rows(&phis[0][0], 2),
                               ns_vec3s_rows(&wis[0][0], 2), ns_vec3s_rows(&wos[0][0], 2),
                               &wis[2][0]),
                  NS_ERR_INVALID_ARGUMENT);
    /* A NULL array with n > 0; a misaligned one. */
    NsVec3s nowi = {NULL, NULL, NULL};
    EXPECT_STATUS(ns_pdf_batch(s, 2, ns_features_rows(&phis[0][0], 2), nowi,
                               ns_vec3s_rows(&wos[0][0], 2), pdfs),
                  NS_ERR_NULL_POINTER);
    EXPECT_STATUS(ns_pdf_batch(s, 1, ns_features_rows(&phis[0][0], 1),
                               ns_vec3s_rows(&wos[0][0], 1), ns_vec3s_rows(&wos[0][0], 1),
                               (float *)((char *)pdfs + 1)),
                  NS_ERR_INVALID_ARGUMENT);
  }
  /* n = 0 is a no-op, whatever the pointers. */
  {
    NsFeatures none_phi;
    for (int k = 0; k < NS_FEATURE_DIM; ++k) none_phi.c[k] = NULL;
    NsVec3s none3 = {NULL, NULL, NULL};
    NsVec2s none2 = {NULL, NULL};
    NsSamplesMut none_out = {NULL, NULL, NULL, NULL, NULL};
    EXPECT_STATUS(ns_sample_batch(s, 0, none_phi, none3, none2, none_out), NS_OK);
    EXPECT_STATUS(ns_pdf_batch(s, 0, none_phi, none3, none3, NULL), NS_OK);
  }
  /* A prepared state used with another sampler. */
  {
    NsSampler *cos = NULL;
    NsPrepared *prep = NULL;
    EXPECT_STATUS(ns_sampler_cosine(&cos), NS_OK);
    EXPECT_STATUS(ns_prepared_new(&prep), NS_OK);
    EXPECT_STATUS(ns_prepared_sample(s, prep, u, &smp), NS_ERR_INVALID_ARGUMENT);
    EXPECT_STATUS(ns_prepare(cos, &phi, up, prep), NS_OK);
    EXPECT_STATUS(ns_prepared_pdf(s, prep, up, &p), NS_ERR_INVALID_ARGUMENT);
    ns_prepared_free(prep);
    ns_sampler_free(cos);
  }
  /* Freeing NULL is fine. */
  ns_blob_free(NULL);
  ns_sampler_free(NULL);
  ns_material_free(NULL);
  ns_prepared_free(NULL);
  printf("  bad input: missing file, corrupted blob, wrong kinds, NULL, NaN, n = 0, overlap\n");
}

/* The measured-material calls on what the fixtures hold (no measured blob is committed: the
 * round trip through a blob written from an RGL file is tests/measured.rs): NULL handles and
 * outputs, and blobs of other kinds, are status codes. */
static void check_measured_errors(const char *root) {
  char path[1024];
  NsBlob *blob = NULL;
  NsMeasured *m = NULL;
  NsVec3 up = {0.0f, 0.0f, 1.0f};
  NsVec2 u = {0.5f, 0.5f};
  NsRgb f;
  float pdf = 0.0f;
  NsMeasuredSample smp;
  EXPECT_STATUS(ns_measured_new(NULL, &m), NS_ERR_NULL_POINTER);
  snprintf(path, sizeof path, "%s/blobs/goat_leather_neural/flow.nsb", root);
  EXPECT_STATUS(ns_blob_open(path, &blob), NS_OK);
  EXPECT_STATUS(ns_measured_new(blob, NULL), NS_ERR_NULL_POINTER);
  EXPECT_STATUS(ns_measured_new(blob, &m), NS_ERR_WRONG_KIND);
  CHECK(m == NULL, "handle written on error");
  ns_blob_free(blob);
  EXPECT_STATUS(ns_measured_eval(NULL, up, up, &f), NS_ERR_NULL_POINTER);
  EXPECT_STATUS(ns_measured_pdf(NULL, up, up, &pdf), NS_ERR_NULL_POINTER);
  EXPECT_STATUS(ns_measured_sample(NULL, up, u, &smp), NS_ERR_NULL_POINTER);
  NsVec3s none = {NULL, NULL, NULL};
  EXPECT_STATUS(ns_measured_pdf_batch(NULL, 0, none, none, NULL), NS_ERR_NULL_POINTER);
  ns_measured_free(NULL);
  printf("  measured material: NULL handles and wrong kinds\n");
}

/* A direction in the upper hemisphere, z in [0.05, 1). */
static NsVec3 upper(void) {
  float z = 0.05f + 0.95f * next_u();
  float phi = 6.2831853f * next_u();
  float s = sqrtf(1.0f - z * z);
  NsVec3 v = {s * cosf(phi), s * sinf(phi), z};
  return v;
}

static int same_bits(const float *a, const float *b, size_t n) {
  return memcmp(a, b, n * sizeof *a) == 0;
}

/* The mint's RGL file through ns_measured_open_bsdf (see the top of this file). */
static void check_measured_file(const char *root) {
  enum { N = 64 };
  char path[1024], cut[1024];
  snprintf(path, sizeof path, "%s/measured/chm_mint_rgb.bsdf", root);
  NsMeasured *m = NULL;
  EXPECT_STATUS(ns_measured_open_bsdf(path, &m), NS_OK);
  if (!m) return;
  float ix[N], iy[N], iz[N], ox[N], oy[N], oz[N], ux[N], uy[N];
  /* Scalar results: f (3), pdf, sample wo (3), pdf, weight (3). */
  float f[3][N], pdf[N], swo[3][N], spdf[N], sw[3][N];
  int sampled = 0;
  float worst_pdf = 0.0f, worst_weight = 0.0f;
  for (int i = 0; i < N; ++i) {
    NsVec3 wi = upper(), wo = upper();
    NsVec2 u = {next_u(), next_u()};
    ix[i] = wi.x, iy[i] = wi.y, iz[i] = wi.z, ox[i] = wo.x, oy[i] = wo.y, oz[i] = wo.z;
    ux[i] = u.x, uy[i] = u.y;
    NsRgb rgb;
    EXPECT_STATUS(ns_measured_eval(m, wi, wo, &rgb), NS_OK);
    CHECK(isfinite(rgb.r) && isfinite(rgb.g) && isfinite(rgb.b) && rgb.r >= 0.0f &&
              rgb.g >= 0.0f && rgb.b >= 0.0f,
          "lane %d: eval (%g, %g, %g)", i, rgb.r, rgb.g, rgb.b);
    f[0][i] = rgb.r, f[1][i] = rgb.g, f[2][i] = rgb.b;
    EXPECT_STATUS(ns_measured_pdf(m, wi, wo, &pdf[i]), NS_OK);
    NsMeasuredSample s;
    NsStatus st = ns_measured_sample(m, wi, u, &s);
    CHECK(st == NS_OK || st == NS_REFUSED, "lane %d: sample returned %s", i, ns_status_name(st));
    swo[0][i] = s.wo.x, swo[1][i] = s.wo.y, swo[2][i] = s.wo.z, spdf[i] = s.pdf;
    sw[0][i] = s.weight.r, sw[1][i] = s.weight.g, sw[2][i] = s.weight.b;
    if (st != NS_OK) continue;
    ++sampled;
    float p = 0.0f;
    EXPECT_STATUS(ns_measured_pdf(m, wi, s.wo, &p), NS_OK);
    float e = fabsf(p - s.pdf) / s.pdf;
    worst_pdf = fmaxf(worst_pdf, e);
    CHECK(e <= 1e-3f, "lane %d: sample pdf %g, ns_measured_pdf %g", i, s.pdf, p);
    NsRgb fs;
    EXPECT_STATUS(ns_measured_eval(m, wi, s.wo, &fs), NS_OK);
    float want[3] = {fs.r * s.wo.z / s.pdf, fs.g * s.wo.z / s.pdf, fs.b * s.wo.z / s.pdf};
    float got[3] = {s.weight.r, s.weight.g, s.weight.b};
    float scale = fmaxf(want[0], fmaxf(want[1], want[2]));
    for (int c = 0; c < 3; ++c) {
      float ew = fabsf(got[c] - want[c]) / scale;
      worst_weight = fmaxf(worst_weight, ew);
      CHECK(ew <= 1e-4f, "lane %d: weight[%d] %g, f cos / pdf %g", i, c, got[c], want[c]);
    }
  }
  CHECK(sampled > N / 2, "only %d of %d lanes sampled", sampled, N);

  /* The batched calls on the same lanes, bit for bit. */
  float bf[3][N], bpdf[N], bwo[3][N], bspdf[N], bsmis[N], bw[3][N];
  NsVec3s wi_s = {ix, iy, iz}, wo_s = {ox, oy, oz};
  NsVec2s u_s = {ux, uy};
  NsRgbMut f_out = {bf[0], bf[1], bf[2]}, w_out = {bw[0], bw[1], bw[2]};
  NsSamplesMut s_out = {bwo[0], bwo[1], bwo[2], bspdf, bsmis};
  EXPECT_STATUS(ns_measured_eval_batch(m, N, wi_s, wo_s, f_out), NS_OK);
  EXPECT_STATUS(ns_measured_pdf_batch(m, N, wi_s, wo_s, bpdf), NS_OK);
  EXPECT_STATUS(ns_measured_sample_batch(m, N, wi_s, u_s, s_out, w_out), NS_OK);
  CHECK(same_bits(&f[0][0], &bf[0][0], 3 * N), "batched eval differs from scalar");
  CHECK(same_bits(pdf, bpdf, N), "batched pdf differs from scalar");
  CHECK(same_bits(&swo[0][0], &bwo[0][0], 3 * N) && same_bits(spdf, bspdf, N) &&
            same_bits(spdf, bsmis, N) &&
            same_bits(&sw[0][0], &bw[0][0], 3 * N),
        "batched sample differs from scalar");
  ns_measured_free(m);

  /* A truncated copy names the file and the field; a missing file is NS_ERR_IO. */
  const char *tmp = getenv("TMPDIR");
  snprintf(cut, sizeof cut, "%s/neusample_check_truncated.bsdf", tmp && *tmp ? tmp : "/tmp");
  FILE *in = fopen(path, "rb"), *out = fopen(cut, "wb");
  CHECK(in && out, "cannot copy %s to %s", path, cut);
  if (in && out) {
    static unsigned char buf[1 << 20];
    size_t len = fread(buf, 1, sizeof buf, in);
    CHECK(len > 1000 && fwrite(buf, 1, len / 2, out) == len / 2, "copy of %s", path);
  }
  if (in) fclose(in);
  if (out) fclose(out);
  NsMeasured *bad = NULL;
  EXPECT_STATUS(ns_measured_open_bsdf(cut, &bad), NS_ERR_MEASURED_FILE);
  CHECK(bad == NULL, "handle written on error");
  CHECK(strstr(ns_last_error(), cut) && strstr(ns_last_error(), "vndf"),
        "message without the file and the field: %s", ns_last_error());
  remove(cut);
  EXPECT_STATUS(ns_measured_open_bsdf(cut, &bad), NS_ERR_IO);
  EXPECT_STATUS(ns_measured_open_bsdf(NULL, &bad), NS_ERR_NULL_POINTER);
  EXPECT_STATUS(ns_measured_open_bsdf(path, NULL), NS_ERR_NULL_POINTER);
  printf("  measured file %s: %d of %d lanes sampled, worst sample pdf %.1e, weight %.1e; "
         "batched = scalar bit for bit; a truncated copy refused\n",
         path, sampled, N, (double)worst_pdf, (double)worst_weight);
}

int main(int argc, char **argv) {
  const char *root = argc > 1 ? argv[1] : "fixtures";
  char path[1024];
  printf("neusample C ABI %s\n", ns_version());
  NsMaterial *first_material = NULL;
  NsSampler *first_sampler = NULL;
  for (size_t a = 0; a < sizeof MATERIALS / sizeof *MATERIALS; ++a) {
    NsBlob *mblob = NULL;
    NsMaterial *m = NULL;
    snprintf(path, sizeof path, "%s/materials/neural/%s.nsb", root, MATERIALS[a]);
    EXPECT_STATUS(ns_blob_open(path, &mblob), NS_OK);
    if (!mblob) return 1;
    NsHeader h;
    EXPECT_STATUS(ns_blob_header(mblob, &h), NS_OK);
    CHECK(h.kind == NS_KIND_NEURAL_MATERIAL && h.feature_dim == NS_FEATURE_DIM,
          "material header");
    EXPECT_STATUS(ns_material_new(mblob, &m), NS_OK);
    ns_blob_free(mblob); /* the material keeps the bytes alive */
    printf("%s (texture %ux%u)\n", MATERIALS[a], h.resolution, h.t_levels);
    NsSampler *cos = NULL;
    EXPECT_STATUS(ns_sampler_cosine(&cos), NS_OK);
    check_sampler("cosine", cos, m);
    ns_sampler_free(cos);
    for (size_t b = 0; b < sizeof METHODS / sizeof *METHODS; ++b) {
      NsBlob *blob = NULL;
      NsSampler *s = NULL;
      snprintf(path, sizeof path, "%s/blobs/%s/%s.nsb", root, MATERIALS[a], METHODS[b]);
      EXPECT_STATUS(ns_blob_open(path, &blob), NS_OK);
      EXPECT_STATUS(ns_sampler_new(blob, &s), NS_OK);
      char label[256];
      size_t len = 0;
      EXPECT_STATUS(ns_blob_label(blob, label, sizeof label, &len), NS_OK);
      CHECK(strlen(label) == (len < sizeof label ? len : sizeof label - 1), "label length");
      ns_blob_free(blob);
      if (!s) continue;
      check_sampler(METHODS[b], s, m);
      if (!first_sampler)
        first_sampler = s;
      else
        ns_sampler_free(s);
    }
    if (!first_material)
      first_material = m;
    else
      ns_material_free(m);
  }
  check_bad_input(root, first_material, first_sampler);
  check_measured_errors(root);
  check_measured_file(root);
  ns_sampler_free(first_sampler);
  ns_material_free(first_material);
  printf("%d passed, %d failed\n", checks - failures, failures);
  return failures == 0 ? 0 : 1;
}
