/* The projection of a point onto a reference path, as ReferencePath.project does it in
 * Python (tracker/paths/reference_path.py), operation by operation, so both give the same
 * numbers to the bit: the nearest point of the path's table (all of it, or a window around
 * a known arc length), then three Newton steps on the cubic spline.
 *
 * Python's semantics are kept where C's differ: the float remainder takes the divisor's
 * sign (CPython's float_rem), min/max return their first argument unless the second is
 * strictly smaller/larger (so a NaN passes through), and the piece holding an arc length is
 * bisect.bisect_right's. Compiled
 * with -ffp-contract=off: no a*b+c is fused, each operation is rounded as in Python.
 *
 * Layouts (all C-contiguous doubles, owned by the caller):
 *   table     3 x n_table: arc lengths, x, y of the table's points
 *   knots     n_pieces + 1 arc lengths of the spline's knots
 *   pieces    n_pieces x 8: per piece, x's cubic (a, b, c, d) then y's, in h = s - knot
 *   geometry  length_m, table_step_m, closed (0 or 1)
 *   out       s_m, lateral_error_m, path_yaw_rad, curvature_1pm
 */
#include <math.h>

static double py_mod(double x, double y) {
    double mod = fmod(x, y);
    if (mod != 0.0) {
        if ((y < 0.0) != (mod < 0.0)) mod += y;
    } else {
        mod = copysign(0.0, y);
    }
    return mod;
}

static double py_max(double a, double b) { return b > a ? b : a; }

/* numpy.maximum: a NaN in either wins. */
static double np_maximum(double a, double b) {
    return (isnan(a) || isnan(b)) ? NAN : (b > a ? b : a);
}

static double py_min(double a, double b) { return b < a ? b : a; }

static long py_imod(long a, long b) {
    long r = a % b;
    return (r != 0 && ((r < 0) != (b < 0))) ? r + b : r;
}

/* x, y and their first and second derivatives in arc length at s (ReferencePath._evaluate). */
static void evaluate(const double *knots, const double *pieces, long n_pieces, double s,
                     double *v) {
    long lo = 0, hi = n_pieces + 1; /* bisect_right over the knots */
    while (lo < hi) {
        long mid = (lo + hi) / 2;
        if (s < knots[mid]) hi = mid; else lo = mid + 1;
    }
    long i = lo - 1;
    if (i < 0) i = 0;
    if (i > n_pieces - 1) i = n_pieces - 1;
    double h = s - knots[i];
    const double *c = pieces + 8 * i;
    double ax = c[0], bx = c[1], cx = c[2], dx = c[3];
    double ay = c[4], by = c[5], cy = c[6], dy = c[7];
    v[0] = ((ax * h + bx) * h + cx) * h + dx;
    v[1] = ((ay * h + by) * h + cy) * h + dy;
    v[2] = (3.0 * ax * h + 2.0 * bx) * h + cx;
    v[3] = (3.0 * ay * h + 2.0 * by) * h + cy;
    v[4] = 6.0 * ax * h + 2.0 * bx;
    v[5] = 6.0 * ay * h + 2.0 * by;
}

/* The first index of the least squared distance over table entries first..last-1 (each taken
 * modulo n_table when wrap is set): numpy's argmin (the table is finite, so a distance is
 * NaN only for a point that is not a number, and then every one is, and both give the
 * first). */
static long nearest(const double *tx, const double *ty, long n_table, long first, long last,
                    int wrap, double x, double y) {
    long best = -1;
    double least = 0.0;
    for (long j = first; j < last; j++) {
        long k = wrap ? py_imod(j, n_table) : j;
        double ex = tx[k] - x, ey = ty[k] - y;
        double d = ex * ex + ey * ey;
        if (best < 0 || d < least) {
            best = k;
            least = d;
        }
    }
    return best;
}

static int project(const double *table, long n_table, const double *knots,
                   const double *pieces, long n_pieces, const double *geometry, double x,
                   double y, int windowed, double near_s, double window_m, double *out) {
    const double *ts = table, *tx = table + n_table, *ty = table + 2 * n_table;
    double length = geometry[0], step = geometry[1];
    int closed = geometry[2] != 0.0;
    long first = 0, last = n_table;
    int wrap = 0;
    if (windowed && closed) {
        long centre = (long)(py_mod(near_s, length) / step);
        long half = (long)(window_m / step) + 1;
        first = centre - half;
        last = centre + half + 1;
        wrap = 1;
    } else if (windowed) {
        long lo = (long)((near_s - window_m) / step);
        first = lo > 0 ? lo : 0;
        long hi = (long)ceil((near_s + window_m) / step) + 1;
        last = hi > first + 1 ? hi : first + 1;
        if (last > n_table) last = n_table;
        if (first >= last) { /* beyond the path's end: search all of it */
            first = 0;
            last = n_table;
        }
    }
    if (n_table < 1 || n_pieces < 1) return 1;
    long i = nearest(tx, ty, n_table, first, last, wrap, x, y);
    double s = ts[i];
    double v[6];
    for (int iteration = 0; iteration < 3; iteration++) {
        evaluate(knots, pieces, n_pieces, s, v);
        double grad = (v[0] - x) * v[2] + (v[1] - y) * v[3];
        double hess = v[2] * v[2] + v[3] * v[3] + (v[0] - x) * v[4] + (v[1] - y) * v[5];
        if (hess <= 1e-9) break;
        s = s - grad / hess;
        s = closed ? py_mod(s, length) : py_min(py_max(s, 0.0), length);
    }
    evaluate(knots, pieces, n_pieces, s, v);
    double yaw = atan2(v[3], v[2]);
    out[0] = s;
    out[1] = -sin(yaw) * (x - v[0]) + cos(yaw) * (y - v[1]);
    out[2] = yaw;
    out[3] = (v[2] * v[5] - v[3] * v[4]) / pow(v[2] * v[2] + v[3] * v[3], 1.5);
    return 0;
}

int cosim_path_project(const double *table, long n_table, const double *knots,
                       const double *pieces, long n_pieces, const double *geometry,
                       double x, double y, int windowed, double near_s, double window_m,
                       double *out) {
    return project(table, n_table, knots, pieces, n_pieces, geometry, x, y, windowed, near_s,
                   window_m, out);
}

/* The arc lengths and spline values of tracker.mpc.horizon_reference's spline reference:
 * the car at (x, y) projected onto the whole path (projection: s_m, lateral_error_m,
 * path_yaw_rad, curvature_1pm), stage k's arc length s_k = s_0 + sum_{j<=k} (v_j + v_{j+1})
 * / 2 * dt (n + 1 speeds, negative ones counted as zero, numpy.maximum's NaN kept), and the
 * spline there (wrapped as ReferencePath.wrap does): the same operations in the same order
 * as numpy's, so the same numbers to the bit. The headings and curvature (arctan2 and a
 * power, which numpy evaluates with SIMD routines of its own) are the caller's.
 *
 * stages: 7 x n (rows s_m, x, y, dx/ds, dy/ds, d2x/ds2, d2y/ds2). Returns 0; 1 for an empty
 * path. */
int cosim_path_horizon(const double *table, long n_table, const double *knots,
                       const double *pieces, long n_pieces, const double *geometry,
                       double x, double y, const double *speeds, long n, double dt,
                       double *projection, double *stages) {
    if (project(table, n_table, knots, pieces, n_pieces, geometry, x, y, 0, 0.0, 0.0,
                projection))
        return 1;
    double length = geometry[0];
    int closed = geometry[2] != 0.0;
    double distance = 0.0, previous_speed = np_maximum(speeds[0], 0.0);
    double v[6];
    for (long k = 0; k < n; k++) {
        double speed = np_maximum(speeds[k + 1], 0.0);
        distance += 0.5 * (previous_speed + speed) * dt;
        previous_speed = speed;
        double s = projection[0] + distance;
        double wrapped = closed ? py_mod(s, length) : py_min(py_max(s, 0.0), length);
        evaluate(knots, pieces, n_pieces, wrapped, v);
        stages[k] = s;
        for (int row = 0; row < 6; row++) stages[(row + 1) * n + k] = v[row];
    }
    return 0;
}
