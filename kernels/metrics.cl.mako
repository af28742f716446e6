<%doc>
metrics.cl.mako: the per-configuration metrics of a sweep chunk on the device, from the per-pixel
outputs the sweep kernel (sweep.cl.mako) left there: only a row of numbers per configuration returns
to the host. One work-item per configuration; float64 throughout (the device needs cl_khr_fp64; the
host computes the same metrics in numpy otherwise). The definitions are s2cl/retrieve/metrics.py's,
which is this kernel's float64 twin (tests/test_metrics_kernel.py).

Template variables
  T          s2cl.cl.vectypes.VecTypes of the sweep (only T.R, the type of `index`, is used)
  kind       "regression" | "classification"
  names      the output columns in order (s2cl.sweep.metrics_kernel.REGRESSION / CLASSIFICATION)
  n_pixels, pitch   pixels per configuration; elements per row of the per-pixel arrays
  regress    status codes whose index enters the regression (regression)
  condition  bool: the median condition code is wanted (IGRM)
  n_classes  classes (classification)
  args, signature  the argument specs (s2cl.sweep.metrics_kernel.ARGS) and the function writing them
Regression (one work-item = one configuration, three passes over its pixels):
  1. counts per status and of pixels on a bound; sums of the index over the regression's pixels (valid:
     status in `regress` and a finite index) and over those not on a bound; the condition-code histogram
     of the fitted pixels (converged, stalled, iteration limit);
  2. moments about each subset's mean: v = x - mean, sums of v^1..4, y, y v, y v^2, y^2;
  3. residuals of the conditioned quadratic (index centred and scaled by its standard deviation, 3 x 3
     normal equations, Gaussian elimination with partial pivoting): the sum of squares, and |r| into
     `scratch` for the median (quickselect; the mean of the two middle values for an even count).
  A configuration whose normal equations are singular (fewer than three distinct index values) or
  that has fewer than 3 regression pixels is marked in `host`: the host recomputes it with numpy
  (the pseudo-inverse solution), so edge cases have one definition.
Classification: the confusion counts per configuration (rows: true class, columns: predicted, the
last: unclassified), the mean omission error over classes with pixels, overall accuracy, the
unclassified and failed fractions.
Output: out[c * len(names) + k], double.
</%doc>
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "common/s2_status.clh"

#define MAD_TO_SIGMA 1.482602218505602
<% K = {name: k for k, name in enumerate(names)} %>
% if kind == "regression":

/* k-th smallest of a[0..n) (n > k), partially sorting a in place: Hoare partition, median of three */
static double s2_select(__global double *a, uint n, uint k)
{
    uint lo = 0, hi = n - 1;
    while (lo < hi) {
        const uint mid = lo + (hi - lo) / 2;
        double x = a[lo], y = a[mid], z = a[hi];
        const double pivot = x < y ? (y < z ? y : (x < z ? z : x)) : (x < z ? x : (y < z ? z : y));
        uint i = lo, j = hi;
        while (i <= j) {
            while (a[i] < pivot) ++i;
            while (a[j] > pivot) --j;
            if (i <= j) {
                const double t = a[i]; a[i] = a[j]; a[j] = t;
                ++i;
                if (j == 0) break;
                --j;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else return a[k];
    }
    return a[k];
}

/* solve the symmetric 3 x 3 system m c = b by Gaussian elimination with partial pivoting; 0 if singular */
static int s2_solve3(double m[9], double b[3], double c[3])
{
    const double scale = fabs(m[0]) + fabs(m[4]) + fabs(m[8]);
    for (int col = 0; col < 3; ++col) {
        int piv = col;
        for (int r = col + 1; r < 3; ++r)
            if (fabs(m[r * 3 + col]) > fabs(m[piv * 3 + col])) piv = r;
        if (!(fabs(m[piv * 3 + col]) > 1e-14 * scale)) return 0;
        if (piv != col) {
            for (int q = 0; q < 3; ++q) { const double t = m[col * 3 + q]; m[col * 3 + q] = m[piv * 3 + q]; m[piv * 3 + q] = t; }
            const double t = b[col]; b[col] = b[piv]; b[piv] = t;
        }
        for (int r = col + 1; r < 3; ++r) {
            const double f = m[r * 3 + col] / m[col * 3 + col];
            for (int q = col; q < 3; ++q) m[r * 3 + q] -= f * m[col * 3 + q];
            b[r] -= f * b[col];
        }
    }
    for (int r = 2; r >= 0; --r) {
        double s = b[r];
        for (int q = r + 1; q < 3; ++q) s -= m[r * 3 + q] * c[q];
        c[r] = s / m[r * 3 + r];
    }
    return 1;
}

/* the conditioned quadratic from moments about the subset's mean: coefficients in u = (x - x0) / scale */
static int s2_quadratic(const double n, const double x0, const double s2v, const double s3v, const double s4v,
                        const double sy, const double syv, const double syv2, double *scale, int *is_const,
                        double coef[3])
{
    const double xs = sqrt(s2v / (n > 0.0 ? n : 1.0));
    *is_const = xs <= 1e-12 * (fabs(x0) > 1.0 ? fabs(x0) : 1.0);
    const double k = *is_const ? 1.0 : xs;
    *scale = k;
    if (*is_const || n == 0.0) {
        coef[0] = n > 0.0 ? sy / n : 0.0;
        coef[1] = 0.0;
        coef[2] = 0.0;
        return 1;
    }
    /* sum u = 0 about the mean */
    const double u2 = s2v / (k * k), u3 = s3v / (k * k * k), u4 = s4v / (k * k * k * k);
    double m[9] = {n, 0.0, u2, 0.0, u2, u3, u2, u3, u4};
    double b[3] = {sy, syv / k, syv2 / (k * k)};
    return s2_solve3(m, b, coef);
}

__kernel void regression_metrics(
    ${signature(args, T)})
{
    const uint c = get_global_id(0);
    if (c >= n_configs)
        return;
    const size_t row = (size_t)c * ${pitch}u;
    __global double *res = scratch + (size_t)c * ${n_pixels}u;
    uint count[6] = {0, 0, 0, 0, 0, 0};
    uint n = 0, nu = 0, nb = 0;
    double sx = 0.0, sxu = 0.0;
% if condition:
    uint hist[256];
    for (int h = 0; h < 256; ++h) hist[h] = 0;
    uint fitted = 0;
% endif
    for (uint p = 0; p < ${n_pixels}u; ++p) {
        const uchar st = status[row + p];
        const uchar bd = bounds[row + p];
        const double x = index[row + p];
        count[st < 6 ? st : 5] += 1;
        nb += bd != 0;
        /* (x - x) == 0 is false for NaN and +-inf: no builtin in the loop */
        if ((${" | ".join(f"(st == {r})" for r in regress)}) && (x - x) == 0.0) {
            ++n;
            sx += x;
            if (bd == 0) { ++nu; sxu += x; }
        }
% if condition:
        if (st == S2_OK || st == S2_STALLED || st == S2_ITERATION_LIMIT) {
            hist[condition[row + p]] += 1;
            ++fitted;
        }
% endif
    }
    const double dn = (double)n, dnu = (double)nu;
    const double x0 = n ? sx / dn : 0.0, x0u = nu ? sxu / dnu : 0.0;
    double m2 = 0.0, m3 = 0.0, m4 = 0.0, sy = 0.0, syv = 0.0, syv2 = 0.0, syy = 0.0;
    double m2u = 0.0, m3u = 0.0, m4u = 0.0, syu = 0.0, syvu = 0.0, syv2u = 0.0;
    for (uint p = 0; p < ${n_pixels}u; ++p) {
        const uchar st = status[row + p];
        const double x = index[row + p];
        if ((${" | ".join(f"(st == {r})" for r in regress)}) && (x - x) == 0.0) {
            const double y = target[p];
            const double v = x - x0, v2 = v * v;
            m2 += v2; m3 += v2 * v; m4 += v2 * v2;
            sy += y; syv += y * v; syv2 += y * v2; syy += y * y;
            if (bounds[row + p] == 0) {
                const double w = x - x0u, w2 = w * w;
                m2u += w2; m3u += w2 * w; m4u += w2 * w2;
                syu += y; syvu += y * w; syv2u += y * w2;
            }
        }
    }
    double coef[3], coefu[3], k, ku;
    int is_const, is_constu;
    const int ok = s2_quadratic(dn, x0, m2, m3, m4, sy, syv, syv2, &k, &is_const, coef);
    const int oku = s2_quadratic(dnu, x0u, m2u, m3u, m4u, syu, syvu, syv2u, &ku, &is_constu, coefu);
    double ss = 0.0, ssu = 0.0;
    uint j = 0;
    for (uint p = 0; p < ${n_pixels}u; ++p) {
        const uchar st = status[row + p];
        const double x = index[row + p];
        if ((${" | ".join(f"(st == {r})" for r in regress)}) && (x - x) == 0.0) {
            const double y = target[p];
            const double u = (x - x0) / k;
            const double r = y - coef[0] - coef[1] * u - coef[2] * u * u;
            ss += r * r;
            res[j++] = r < 0.0 ? -r : r;
            if (bounds[row + p] == 0) {
                const double w = (x - x0u) / ku;
                const double ru = y - coefu[0] - coefu[1] * w - coefu[2] * w * w;
                ssu += ru * ru;
            }
        }
    }
    double median = NAN;
    if (n) {
        const uint mid = n / 2;
        const double upper = s2_select(res, n, mid);
        if (n % 2) {
            median = upper;
        } else {
            double lower = res[0];
            for (uint q = 1; q < mid; ++q) lower = res[q] > lower ? res[q] : lower;
            median = 0.5 * (lower + upper);
        }
    }
    const double npx = (double)${n_pixels};
    __global double *o = out + (size_t)c * ${len(names)}u;
    const double ybar = n ? sy / dn : 0.0;
    const double ss_tot = syy - dn * ybar * ybar;
    const double rms = n ? sqrt(ss / dn) : NAN;
    o[${K["rms"]}] = rms;
    o[${K["r2"]}] = n ? (ss_tot > 0.0 ? 1.0 - ss / ss_tot : 0.0) : NAN;
    o[${K["robust_rms"]}] = MAD_TO_SIGMA * median;
    o[${K["n_valid"]}] = dn;
    o[${K["constant_index"]}] = (is_const && n) ? 1.0 : 0.0;
    o[${K["rms_unbounded"]}] = nb ? (nu ? sqrt(ssu / dnu) : NAN) : rms;
    o[${K["converged_fraction"]}] = count[S2_OK] / npx;
    o[${K["stalled_fraction"]}] = count[S2_STALLED] / npx;
    o[${K["iteration_limit_fraction"]}] = count[S2_ITERATION_LIMIT] / npx;
    o[${K["degenerate_fraction"]}] = count[S2_DEGENERATE] / npx;
    o[${K["invalid_fraction"]}] = count[S2_INVALID] / npx;
    o[${K["failed_fraction"]}] = count[S2_DEGENERATE] / npx + count[S2_INVALID] / npx;
    o[${K["bound_fraction"]}] = nb / npx;
    o[${K["excluded_fraction"]}] = 1.0 - dn / npx;
% if condition:
    double med_code = NAN;
    if (fitted) {
        const uint want = (fitted + 1) / 2;
        uint cum = 0;
        for (int h = 0; h < 256; ++h) {
            cum += hist[h];
            if (cum >= want) { med_code = (double)h; break; }
        }
    }
    o[${K["log10_condition_median"]}] = med_code / 20.0;
% endif
    /* singular normal equations or too few pixels: the host's numpy twin decides (pseudo-inverse) */
    o[${K["host"]}] = (!ok || (nb && nu && !oku) || (n && n < 3) || (nb && nu && nu < 3)) ? 1.0 : 0.0;
}
% else:

__kernel void classification_metrics(
    ${signature(args, T)})
{
    const uint c = get_global_id(0);
    if (c >= n_configs)
        return;
    const size_t row = (size_t)c * ${pitch}u;
    uint conf[${n_classes * (n_classes + 1)}];
    for (int q = 0; q < ${n_classes * (n_classes + 1)}; ++q) conf[q] = 0;
    uint failed = 0;
    for (uint p = 0; p < ${n_pixels}u; ++p) {
        const uchar st = status[row + p];
        const int truth = (int)target[p];
        const int pred = st == S2_OK ? (int)index[row + p] : ${n_classes};
        conf[truth * ${n_classes + 1} + (pred >= 0 && pred < ${n_classes} ? pred : ${n_classes})] += 1;
        failed += (st == S2_INVALID) | (st == S2_DEGENERATE);
    }
    double omission = 0.0;
    uint with_pixels = 0, correct = 0, total = 0, unclassified = 0;
    for (int i = 0; i < ${n_classes}; ++i) {
        uint per_class = 0;
        for (int q = 0; q <= ${n_classes}; ++q) per_class += conf[i * ${n_classes + 1} + q];
        const uint hit = conf[i * ${n_classes + 1} + i];
        if (per_class) { omission += 1.0 - (double)hit / per_class; ++with_pixels; }
        correct += hit;
        total += per_class;
        unclassified += conf[i * ${n_classes + 1} + ${n_classes}];
    }
    const double npx = (double)${n_pixels};
    __global double *o = out + (size_t)c * ${len(names)}u;
    o[${K["omission_error_pct"]}] = with_pixels ? 100.0 * omission / with_pixels : NAN;
    o[${K["overall_accuracy_pct"]}] = 100.0 * correct / (double)(total > 0 ? total : 1);
    o[${K["unclassified_fraction"]}] = unclassified / npx;
    o[${K["failed_fraction"]}] = failed / npx;
    o[${K["host"]}] = 0.0;
}
% endif
