/*
 * The Newton stepper of a step kernel: LU with row scaling and partial pivoting, the
 * rounding floors, Newton with chord updates and polishing, the warm start and its
 * extrapolation, the trust region, and simulate (symgroupoid.stepper; its NumPy twin is
 * _numpy.py beside this file).  The functions a kernel generates (residual, Jacobian,
 * scale, prediction, state update) are declared in stepper.h; see there for how to compile
 * the library on its own.
 */
#include "stepper.h"
#include "prologue.h"

/* The Newton stepper's loops run over the (compile-time) number of unknowns; for a few
 * unknowns they are unrolled completely (no loop overhead, constant offsets).  Up to 8: at
 * 16 the unrolled LU doubles the compiler's time (planar chain of 16 links: 1.1 s -> 2.4 s
 * at -O3) for a step dominated by F and J. */
#if SG_N_UNKNOWNS <= 8 && defined(__clang__)
#define SG_UNROLL _Pragma("clang loop unroll(full)")
#elif SG_N_UNKNOWNS <= 8 && defined(__GNUC__)
#define SG_UNROLL _Pragma("GCC unroll 8")
#else
#define SG_UNROLL
#endif

void SG_NAME(default_options)(SG_NAME(options) *options)
{
    options->tol_residual = 0.0;
    options->floor_factor = 8.0;
    options->tol_step = 1e-16;
    options->max_iterations = 50;
    options->extrapolate = 1;
    options->trust_factor = 10.0;
}

/* The small helpers of the stepper are declared inline, so that a build at -O1 (a small
 * step's default, see the runtime's optimisation_flags) inlines them as -O2 and -O3 do.
 * The bits of |x| as an integer: for x >= 0 the integers are ordered as the doubles, above
 * every finite |x| come the infinities, then the NaNs (all >= SG_INF_BITS) */
#define SG_INF_BITS UINT64_C(0x7ff0000000000000)
static inline uint64_t SG_NAME(abs_bits)(double x)
{
    uint64_t bits;
    memcpy(&bits, &x, sizeof bits);
    return bits & UINT64_C(0x7fffffffffffffff);
}

static inline double SG_NAME(from_bits)(uint64_t bits)
{
    double x;
    memcpy(&x, &bits, sizeof x);
    return x;
}

/* max_i |v_i|; if an entry is not finite, the first such |v_i| (fmax would drop NaN).  One
 * integer pass over the bits of |v_i| (see SG_NAME(abs_bits)), and a second pass only when the
 * largest is not finite. */
static inline double SG_NAME(norm_inf)(const double *v, int n)
{
    uint64_t m = 0;
    int i;
    for (i = 0; i < n; ++i) {
        const uint64_t a = SG_NAME(abs_bits)(v[i]);
        m = a > m ? a : m;
    }
    if (m < SG_INF_BITS) {
        return SG_NAME(from_bits)(m);
    }
    for (i = 0; SG_NAME(abs_bits)(v[i]) < SG_INF_BITS; ++i) {
    }
    return fabs(v[i]);
}

/* frexp's exponent of a positive finite x (x = m 2^e, 0.5 <= m < 1), read from the bits of
 * an IEEE-754 double for normal x (no library call), from frexp for subnormal x. */
static inline int SG_NAME(binary_exponent)(double x)
{
    uint64_t bits;
    int biased;
    memcpy(&bits, &x, sizeof bits);
    biased = (int)((bits >> 52) & 0x7ff);
    if (biased == 0) {
        int e;
        (void)frexp(x, &e);
        return e;
    }
    return biased - 1022;
}

/* 2^k for -1022 <= k <= 1023, exactly (the bits of a normal double) */
static inline double SG_NAME(power_of_two)(int k)
{
    const uint64_t bits = (uint64_t)(k + 1023) << 52;
    double x;
    memcpy(&x, &bits, sizeof x);
    return x;
}

#if SG_BANDED
/* A kernel whose Jacobian is banded (SG_BANDED) once its unknowns (and equations) are
 * taken in the order SG_BAND_ORDER -- entry (i, j) of the reordered matrix
 * B = J[order[i]][order[j]] is zero unless -SG_BAND_KL <= j - i <= SG_BAND_KU, as the code
 * generator found from the program's sparsity (a chain in maximal coordinates, whose joints couple neighbours only) -- factors
 * B in band storage: row i holds columns i - KL ... i + KL + KU (the KL more on the right
 * take the fill of the row swaps), so the LU costs O(n KL (KL + KU)) instead of O(n^3). */
#define SG_BAND_WIDTH (2 * SG_BAND_KL + SG_BAND_KU + 1)
#define SG_LU_ENTRIES (SG_N_UNKNOWNS * SG_BAND_WIDTH)
static const int SG_NAME(band_order)[SG_N_UNKNOWNS] = SG_BAND_ORDER;
/* entry (i, j) of the band storage A (valid for i - KL <= j <= i + KL + KU) */
#define SG_BAND_AT(A, i, j) (A)[(i) * SG_BAND_WIDTH + (j) - (i) + SG_BAND_KL]
/* The kernel writes its Jacobian in band form too (SG_NAME(residual_jacobian_band)): entry
 * (i, j) of B, i - KL <= j <= i + KU, at SG_JACOBIAN_AT(J, i, j); the entries outside the
 * band are zero and never stored, so nothing the stepper does per step touches n^2 memory.
 * The kernel's SG_NAME(residual_jacobian) gives the whole matrix from it. */
#define SG_JACOBIAN_WIDTH (SG_BAND_KL + SG_BAND_KU + 1)
#define SG_JACOBIAN_ENTRIES (SG_N_UNKNOWNS * SG_JACOBIAN_WIDTH)
#define SG_JACOBIAN_AT(J, i, j) (J)[(i) * SG_JACOBIAN_WIDTH + (j) - (i) + SG_BAND_KL]
#define SG_JACOBIAN SG_NAME(residual_jacobian_band_hoisted)
#if SG_TIME_ROW >= 0
#error "a step on a time groupoid replaces a row of its Jacobian: it has no band form"
#endif
void SG_NAME(residual_jacobian_band)(const double *u, const double *known, const double *p, double *F, double *J);
void SG_NAME(residual_jacobian_band_hoisted)(const double *u, const double *known, const double *p, const double *h, double *F, double *J);

/* S_i += |J_ij| a_j for j = 0, 1, ... (each S_i's terms in that order) from the band form:
 * the band's rows of each column; a zero entry outside the band adds |0| a_j, which is +0
 * (nothing) for a finite a_j and NaN otherwise, as the dense sum would */
static void SG_NAME(column_sums)(const double *J, const double *a, double *S)
{
    const int n = SG_N_UNKNOWNS;
    const int *order = SG_NAME(band_order);
    int position[SG_N_UNKNOWNS];
    int j, r;
    for (r = 0; r < n; ++r) {
        position[order[r]] = r;
    }
    for (j = 0; j < n; ++j) {
        const int c = position[j];
        const int lo = c - SG_BAND_KU > 0 ? c - SG_BAND_KU : 0;
        const int hi = c + SG_BAND_KL < n - 1 ? c + SG_BAND_KL : n - 1;
        for (r = lo; r <= hi; ++r) {
            S[order[r]] += fabs(SG_JACOBIAN_AT(J, r, c)) * a[j];
        }
        if (!(a[j] < INFINITY)) {
            for (r = 0; r < n; ++r) {
                if (r < lo || r > hi) {
                    S[order[r]] += 0.0 * a[j];
                }
            }
        }
    }
}
#else
#define SG_LU_ENTRIES (SG_N_UNKNOWNS * SG_N_UNKNOWNS)
#define SG_JACOBIAN_ENTRIES (SG_N_EQUATIONS * SG_N_UNKNOWNS)
#define SG_JACOBIAN SG_NAME(residual_jacobian_hoisted)
void SG_NAME(residual_jacobian_hoisted)(const double *u, const double *known, const double *p, const double *h, double *F, double *J);
#endif
/* the values of the known arrow F and J read (SG_NAME(hoist)), computed once per step */
#define SG_HOISTED_ENTRIES (SG_N_HOISTED > 0 ? SG_N_HOISTED : 1)

/* The pivot of a column: the offset of the first largest |entry| among count entries
 * a[0], a[stride], ... (the partial pivoting of the dense and the band LU), *amax its size */
static inline int SG_NAME(pivot)(const double *a, int stride, int count, double *amax)
{
    int i, piv = 0;
    double m = fabs(a[0]);
    for (i = 1; i < count; ++i) {
        const double v = fabs(a[(size_t)i * stride]);
        piv = v > m ? i : piv;
        m = v > m ? v : m;
    }
    *amax = m;
    return piv;
}

/* Exchange count entries of two rows */
static inline void SG_NAME(swap)(double *x, double *y, int count)
{
    int j;
    for (j = 0; j < count; ++j) {
        const double t = x[j];
        x[j] = y[j];
        y[j] = t;
    }
}

/* The factors of a Jacobian (SG_NAME(lu_factor)): the scaled, permuted and eliminated matrix
 * A (row-major; L's multipliers below the diagonal, U on and above it), the row exponents e
 * with their scales s[i] = 2^-e[i] (0 where 2^-e[i] is not a normal double: that row is
 * scaled with ldexp), normal = 1 when no row needs ldexp, the pivot rows perm, the
 * reciprocal pivots inv, and the row sums sum_j |J_ij| of J (from j = 0 up; see
 * SG_NAME(explained_by_rounding)).  A band kernel's A is in band storage (SG_BAND_AT). */
typedef struct {
    double A[SG_LU_ENTRIES];
    double s[SG_N_UNKNOWNS];
    double inv[SG_N_UNKNOWNS];
    double row_max[SG_N_UNKNOWNS];
    int e[SG_N_UNKNOWNS];
    int perm[SG_N_UNKNOWNS];
    int normal;
} SG_NAME(lu);

/* Gaussian elimination with partial pivoting of the row-scaled n x n matrix A (row-major,
 * overwritten by L's multipliers below the diagonal and U on and above it): perm[k] the row
 * swapped into place k (the first largest |entry| of column k), inv[k] the reciprocal pivot.
 * Returns SG_SINGULAR_JACOBIAN at the first pivot not above n * DBL_EPSILON, else SG_OK.
 *
 * Entry (i, j) receives the updates A_ij -= l_ik u_kj of k = 0, 1, ... in that order, each
 * rounded (no fused multiply-add: kernels are compiled with -ffp-contract=off), and a zero
 * multiplier l_ik is skipped; the NumPy twin (_numpy.py, lu_factor) performs the same
 * operations.  Up to SG_LU_PANEL_FROM unknowns the updates are applied column by column (the
 * textbook right-looking order); from there on a panel of SG_LU_PANEL columns is eliminated
 * first and the rest of its rows and the rows below receive the panel's updates together,
 * every entry once per panel instead of once per column (fewer passes over a matrix that
 * no longer fits in the first-level cache; the loops over a row vectorise).  The order of
 * the updates of every entry, and so every bit of the result, is the same either way. */
#define SG_LU_PANEL 8
#define SG_LU_PANEL_FROM 24

#if !SG_BANDED
/* Columns [k0, k1) of the elimination: pivot search, swap of whole rows, multipliers, and
 * the updates of the panel's own columns only (the columns from k1 on are left to
 * SG_NAME(row_updates) and SG_NAME(panel_row_update)). */
static inline int SG_NAME(eliminate_columns)(double *A, double *inv, int *perm, int k0, int k1)
{
    const int n = SG_N_UNKNOWNS;
    const double tiny = n * DBL_EPSILON;
    int i, j, k;
    SG_UNROLL
    for (k = k0; k < k1; ++k) {
        double amax;
        const int piv = k + SG_NAME(pivot)(&A[k * n + k], n, n - k, &amax);
        if (!(amax > tiny)) {
            return SG_SINGULAR_JACOBIAN;
        }
        perm[k] = piv;
        if (piv != k) {
            SG_NAME(swap)(&A[k * n], &A[piv * n], n);
        }
        inv[k] = 1.0 / A[k * n + k];
        SG_UNROLL
        for (i = k + 1; i < n; ++i) {
            const double l = A[i * n + k] * inv[k];
            A[i * n + k] = l;
            if (l != 0.0) {
                SG_UNROLL
                for (j = k + 1; j < k1; ++j) {
                    A[i * n + j] -= l * A[k * n + j];
                }
            }
        }
    }
    return SG_OK;
}

#if SG_N_UNKNOWNS < SG_LU_PANEL_FROM
static int SG_NAME(eliminate)(double *A, double *inv, int *perm)
{
    return SG_NAME(eliminate_columns)(A, inv, perm, 0, SG_N_UNKNOWNS);
}
#else
/* row r (from column k1 on) minus its multipliers l[0..SG_LU_PANEL) times the panel's rows
 * u, u + n, ...: the SG_LU_PANEL updates of each entry in order, none skipped (every l is
 * nonzero) */
static inline void SG_NAME(panel_row_update)(double *restrict r, const double *restrict u, const double *l, int k1)
{
    const int n = SG_N_UNKNOWNS;
    const double l0 = l[0], l1 = l[1], l2 = l[2], l3 = l[3], l4 = l[4], l5 = l[5], l6 = l[6], l7 = l[7];
    const double *restrict u0 = u, *restrict u1 = u + n, *restrict u2 = u + 2 * n, *restrict u3 = u + 3 * n;
    const double *restrict u4 = u + 4 * n, *restrict u5 = u + 5 * n, *restrict u6 = u + 6 * n, *restrict u7 = u + 7 * n;
    int j;
    for (j = k1; j < n; ++j) {
        double t = r[j];
        t -= l0 * u0[j];
        t -= l1 * u1[j];
        t -= l2 * u2[j];
        t -= l3 * u3[j];
        t -= l4 * u4[j];
        t -= l5 * u5[j];
        t -= l6 * u6[j];
        t -= l7 * u7[j];
        r[j] = t;
    }
}

/* row i from column k1 on: the updates of the panel rows kk in [k0, k) in order, a zero
 * multiplier skipped */
static inline void SG_NAME(row_updates)(double *A, int i, int k0, int k, int k1)
{
    const int n = SG_N_UNKNOWNS;
    int kk, j;
    for (kk = k0; kk < k; ++kk) {
        const double l = A[i * n + kk];
        if (l != 0.0) {
            for (j = k1; j < n; ++j) {
                A[i * n + j] -= l * A[kk * n + j];
            }
        }
    }
}

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__GLIBC__) \
    && !defined(__AVX2__)
/* the panel updates also in AVX-512 and AVX2 instructions, the widest the processor has
 * chosen when the kernel is loaded: the same multiplications and subtractions, so the same
 * bits.  A unit compiled for AVX2 or wider already (the library's builds add the widest
 * extension the processor has) is its own widest copy: one copy, a third of the compiler's
 * work on these loops, kept out of line as the clones are (inlined into the solver, the
 * 16-body chain stepped 4 % slower). */
#define SG_VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#elif defined(__GNUC__)
#define SG_VECTOR_CLONES __attribute__((noinline))
#else
#define SG_VECTOR_CLONES
#endif

SG_VECTOR_CLONES
static int SG_NAME(eliminate)(double *A, double *inv, int *perm)
{
    const int n = SG_N_UNKNOWNS;
    int k0, k, i;
    for (k0 = 0; k0 < n; k0 += SG_LU_PANEL) {
        const int k1 = k0 + SG_LU_PANEL < n ? k0 + SG_LU_PANEL : n;
        const int status = SG_NAME(eliminate_columns)(A, inv, perm, k0, k1);
        if (status != SG_OK) {
            return status;
        }
        for (k = k0 + 1; k < k1; ++k) { /* the panel's rows of U */
            SG_NAME(row_updates)(A, k, k0, k, k1);
        }
        for (i = k1; i < n; ++i) { /* the rows below */
            const double *l = A + i * n + k0;
            int nonzero = k1 - k0 == SG_LU_PANEL;
            for (k = k0; k < k1; ++k) {
                nonzero &= l[k - k0] != 0.0;
            }
            if (nonzero) {
                SG_NAME(panel_row_update)(A + i * n, A + k0 * n, l, k1);
            } else {
                SG_NAME(row_updates)(A, i, k0, k1, k1);
            }
        }
    }
    return SG_OK;
}
#endif
#endif /* !SG_BANDED */

#if SG_BANDED
/* The reordered, row-scaled Jacobian in the LU's band storage (zero outside its band) from
 * the kernel's band form J: entry (i, j) is B_ij scaled by the power of two of row order[i] */
static void SG_NAME(band_fill)(const double *J, const double *s, const int *e, double *A)
{
    const int n = SG_N_UNKNOWNS;
    const int *order = SG_NAME(band_order);
    int i, j;
    for (i = 0; i < SG_LU_ENTRIES; ++i) {
        A[i] = 0.0;
    }
    for (i = 0; i < n; ++i) {
        const int r = order[i];
        const int lo = i - SG_BAND_KL > 0 ? i - SG_BAND_KL : 0;
        const int hi = i + SG_BAND_KU < n - 1 ? i + SG_BAND_KU : n - 1;
        for (j = lo; j <= hi; ++j) {
            const double a = SG_JACOBIAN_AT(J, i, j);
            SG_BAND_AT(A, i, j) = s[r] != 0.0 ? a * s[r] : ldexp(a, -e[r]);
        }
    }
}

/* Gaussian elimination with partial pivoting in band storage (LAPACK's dgbtf2 order): at
 * column k the pivot is the first largest |entry| of rows k ... k + KL; rows k and perm[k]
 * are swapped from column k on (the multipliers already stored stay where they are: the
 * solve applies the swap of step k before the multipliers of column k, as LAPACK's dgbtrs
 * does); the multipliers of rows k + 1 ... k + KL are stored in column k and the rows updated
 * over the columns row k's U can reach (k + KL + KU), a zero multiplier skipped.  Returns
 * SG_SINGULAR_JACOBIAN at the first pivot not above n * DBL_EPSILON, else SG_OK. */
static int SG_NAME(band_eliminate)(double *A, double *inv, int *perm)
{
    const int n = SG_N_UNKNOWNS;
    const double tiny = n * DBL_EPSILON;
    int i, j, k;
    for (k = 0; k < n; ++k) {
        const int last = k + SG_BAND_KL < n - 1 ? k + SG_BAND_KL : n - 1;
        const int end = k + SG_BAND_KL + SG_BAND_KU < n - 1 ? k + SG_BAND_KL + SG_BAND_KU : n - 1;
        double amax; /* column k of rows k ... last: SG_BAND_WIDTH - 1 apart in storage */
        const int piv = k + SG_NAME(pivot)(&SG_BAND_AT(A, k, k), SG_BAND_WIDTH - 1, last - k + 1,
                                           &amax);
        if (!(amax > tiny)) {
            return SG_SINGULAR_JACOBIAN;
        }
        perm[k] = piv;
        if (piv != k) { /* columns k ... end of both rows (each contiguous in storage) */
            SG_NAME(swap)(&SG_BAND_AT(A, k, k), &SG_BAND_AT(A, piv, k), end - k + 1);
        }
        inv[k] = 1.0 / SG_BAND_AT(A, k, k);
        for (i = k + 1; i <= last; ++i) {
            const double l = SG_BAND_AT(A, i, k) * inv[k];
            SG_BAND_AT(A, i, k) = l;
            if (l != 0.0) {
                for (j = k + 1; j <= end; ++j) {
                    SG_BAND_AT(A, i, j) -= l * SG_BAND_AT(A, k, j);
                }
            }
        }
    }
    return SG_OK;
}
#endif

#if !SG_BANDED && SG_N_UNKNOWNS >= SG_LU_PANEL_FROM
/* rmax[i]: the bits of row i's largest |J_ij| (SG_NAME(abs_bits)) of a large dense Jacobian,
 * compared as signed integers (the bits of an absolute value are below 2^63, so the order is
 * the same), which the vector copies compare in one instruction */
SG_VECTOR_CLONES
static void SG_NAME(row_maxima)(const double *J, uint64_t *rmax)
{
    const int n = SG_N_UNKNOWNS;
    int i, j;
    for (i = 0; i < n; ++i) {
        int64_t m = 0;
        for (j = 0; j < n; ++j) {
            int64_t a;
            memcpy(&a, J + i * n + j, sizeof a);
            a &= INT64_MAX;
            m = a > m ? a : m;
        }
        rmax[i] = (uint64_t)m;
    }
}

/* A = the rows of J scaled by s (powers of two: exact), in the vector copies */
SG_VECTOR_CLONES
static void SG_NAME(scale_rows)(const double *J, const double *s, double *A)
{
    const int n = SG_N_UNKNOWNS;
    int i, j;
    for (i = 0; i < n; ++i) {
        const double si = s[i];
        for (j = 0; j < n; ++j) {
            A[i * n + j] = J[i * n + j] * si;
        }
    }
}

/* The factors of a large dense Jacobian are kept transposed (L's multipliers above the
 * diagonal, U below), so that both substitutions of SG_NAME(lu_apply) read their columns
 * contiguously; n(n-1)/2 exchanges once per factorisation, against n^3/3 operations */
static void SG_NAME(transpose)(double *A)
{
    const int n = SG_N_UNKNOWNS;
    int i, j;
    for (i = 0; i < n; ++i) {
        for (j = i + 1; j < n; ++j) {
            const double t = A[i * n + j];
            A[i * n + j] = A[j * n + i];
            A[j * n + i] = t;
        }
    }
}

/* The substitutions of the transposed factors T = A^T (SG_NAME(transpose)), b already scaled
 * and swapped: forward, column k of L taken off the b_i below it (T's row k, contiguous), then
 * back, column by column: x_j once known taken off every b_i above it (the updates of each b_i
 * in the order j = n-1, n-2, ...).  Four columns at a time: their triangle first, then one
 * pass over the entries beyond it, which takes the four columns off each b_i in the same
 * order, one rounding each, reading and writing b_i once instead of four times.  Every b_i
 * receives the same operations in the same order as from the row-major factors, so the same
 * bits, in the widest vector instructions */
SG_VECTOR_CLONES
static void SG_NAME(substitute)(const double *T, const double *inv, double *b)
{
    const int n = SG_N_UNKNOWNS;
    int i, k;
    for (k = 0; k + 4 <= n; k += 4) {
        const double *c0 = T + k * n, *c1 = c0 + n, *c2 = c1 + n, *c3 = c2 + n;
        const double x0 = b[k];
        const double x1 = b[k + 1] - c0[k + 1] * x0;
        const double x2 = (b[k + 2] - c0[k + 2] * x0) - c1[k + 2] * x1;
        const double x3 = ((b[k + 3] - c0[k + 3] * x0) - c1[k + 3] * x1) - c2[k + 3] * x2;
        b[k + 1] = x1;
        b[k + 2] = x2;
        b[k + 3] = x3;
        for (i = k + 4; i < n; ++i) {
            b[i] = (((b[i] - c0[i] * x0) - c1[i] * x1) - c2[i] * x2) - c3[i] * x3;
        }
    }
    for (; k < n; ++k) {
        const double x = b[k];
        const double *column = T + k * n;
        for (i = k + 1; i < n; ++i) {
            b[i] -= column[i] * x;
        }
    }
    for (i = n - 1; i >= 3; i -= 4) {
        const double *c0 = T + i * n, *c1 = c0 - n, *c2 = c1 - n, *c3 = c2 - n;
        const double x0 = b[i] * inv[i];
        const double x1 = (b[i - 1] - c0[i - 1] * x0) * inv[i - 1];
        const double x2 = ((b[i - 2] - c0[i - 2] * x0) - c1[i - 2] * x1) * inv[i - 2];
        const double x3 = (((b[i - 3] - c0[i - 3] * x0) - c1[i - 3] * x1) - c2[i - 3] * x2)
                          * inv[i - 3];
        b[i] = x0;
        b[i - 1] = x1;
        b[i - 2] = x2;
        b[i - 3] = x3;
        for (k = 0; k < i - 3; ++k) {
            b[k] = (((b[k] - c0[k] * x0) - c1[k] * x1) - c2[k] * x2) - c3[k] * x3;
        }
    }
    for (; i >= 0; --i) {
        const double x = b[i] * inv[i];
        const double *column = T + i * n;
        b[i] = x;
        for (k = 0; k < i; ++k) {
            b[k] -= column[k] * x;
        }
    }
}
#endif

/* LU factorisation of J (row-major, left unchanged) into f.  Every row of J is first scaled
 * by the power of two 2^-e[i] that brings the row's largest |entry| into [1/2, 1) (exact, no
 * rounding), so the singularity test is relative to the size of each equation, not to the
 * largest entry of J: equations of very different magnitudes are not mistaken for a singular
 * system.  Partial pivoting (perm[k]: the row swapped into place k; the first largest |entry|
 * of the column), one division per column (inv: reciprocal pivots), zero multipliers skipped.
 * Returns SG_OK; SG_SINGULAR_JACOBIAN when a row is zero or a pivot is not above
 * n * DBL_EPSILON (numerically singular); SG_NON_FINITE when an entry is not finite
 * (overflow or NaN); the first failing row decides. */
static int SG_NAME(lu_factor)(const double *J, SG_NAME(lu) *f)
{
    const int n = SG_N_UNKNOWNS;
    double *A = f->A;
    uint64_t rmax[SG_N_UNKNOWNS];
    int i, j;
#if SG_BANDED
    for (i = 0; i < n; ++i) { /* the same largest |entry| from the band's entries only */
        const int r = SG_NAME(band_order)[i];
        const int lo = i - SG_BAND_KL > 0 ? i - SG_BAND_KL : 0;
        const int hi = i + SG_BAND_KU < n - 1 ? i + SG_BAND_KU : n - 1;
        uint64_t m = 0;
        for (j = lo; j <= hi; ++j) {
            const uint64_t a = SG_NAME(abs_bits)(SG_JACOBIAN_AT(J, i, j));
            m = a > m ? a : m;
        }
        rmax[r] = m;
    }
#elif SG_N_UNKNOWNS >= SG_LU_PANEL_FROM
    (void)j;
    SG_NAME(row_maxima)(J, rmax);
#else
    SG_UNROLL
    for (i = 0; i < n; ++i) { /* the bits of every row's largest |entry| (SG_NAME(abs_bits)), its sum */
        uint64_t m = 0;
        SG_UNROLL
        for (j = 0; j < n; ++j) {
            const uint64_t a = SG_NAME(abs_bits)(J[i * n + j]);
            m = a > m ? a : m;
        }
        rmax[i] = m;
    }
#endif
    for (i = 0; i < n; ++i) { /* the first failing row decides the status */
        if (rmax[i] >= SG_INF_BITS) {
            return SG_NON_FINITE;
        }
        if (rmax[i] == 0) {
            return SG_SINGULAR_JACOBIAN;
        }
    }
    f->normal = 1;
    SG_UNROLL
    for (i = 0; i < n; ++i) {
        f->row_max[i] = SG_NAME(from_bits)(rmax[i]);
        f->e[i] = SG_NAME(binary_exponent)(SG_NAME(from_bits)(rmax[i]));
        if (f->e[i] > -1000 && f->e[i] < 1000) {
            f->s[i] = SG_NAME(power_of_two)(-f->e[i]);
        } else { /* 2^-e[i] is not a normal double: scale with ldexp (still exact) */
            f->s[i] = 0.0;
            f->normal = 0;
        }
    }
#if SG_BANDED
    (void)j;
    SG_NAME(band_fill)(J, f->s, f->e, A);
    return SG_NAME(band_eliminate)(A, f->inv, f->perm);
#else
    if (f->normal) {
#if SG_N_UNKNOWNS >= SG_LU_PANEL_FROM
        SG_NAME(scale_rows)(J, f->s, A);
#else
        SG_UNROLL
        for (i = 0; i < n; ++i) {
            SG_UNROLL
            for (j = 0; j < n; ++j) {
                A[i * n + j] = J[i * n + j] * f->s[i];
            }
        }
#endif
    } else {
        for (i = 0; i < n; ++i) {
            for (j = 0; j < n; ++j) {
                A[i * n + j] = f->s[i] != 0.0 ? J[i * n + j] * f->s[i] : ldexp(J[i * n + j], -f->e[i]);
            }
        }
    }
    /* every entry now lies in [-1, 1]; with partial pivoting the elimination grows them by
     * at most 2^(n-1), so no overflow (and no NaN) can arise from here on */
#if SG_N_UNKNOWNS < SG_LU_PANEL_FROM
    return SG_NAME(eliminate)(A, f->inv, f->perm);
#else
    {
        const int status = SG_NAME(eliminate)(A, f->inv, f->perm);
        if (status == SG_OK) {
            SG_NAME(transpose)(A);
        }
        return status;
    }
#endif
#endif
}

/* Solve J x = b with the factors of SG_NAME(lu_factor) (x returned in b): the same row
 * scaling, the row swaps, forward and back substitution.  Returns SG_OK, or
 * SG_NON_FINITE when x is not finite -- in particular whenever b or its scaling is not
 * finite: a non-finite entry of the scaled b stays non-finite through the substitutions (it
 * is only multiplied by finite multipliers and reciprocal pivots -- a zero one gives NaN --
 * and added to other entries), so one test of x covers both.  Every multiplier is applied,
 * zero ones too (a test per multiplier costs more than the multiplication it would skip). */
static int SG_NAME(lu_apply)(const SG_NAME(lu) *f, double *b)
{
    const int n = SG_N_UNKNOWNS;
    const double *A = f->A;
    int i, j, k;
    if (f->normal) {
        SG_UNROLL
        for (i = 0; i < n; ++i) {
            b[i] *= f->s[i];
        }
    } else {
        for (i = 0; i < n; ++i) {
            b[i] = f->s[i] != 0.0 ? b[i] * f->s[i] : ldexp(b[i], -f->e[i]);
        }
    }
#if SG_BANDED
    (void)j;
    {
        const int *order = SG_NAME(band_order);
        double y[SG_N_UNKNOWNS];
        for (i = 0; i < n; ++i) { /* the reordered right-hand side */
            y[i] = b[order[i]];
        }
        for (k = 0; k < n; ++k) { /* step k's row swap, then its multipliers */
            const int last = k + SG_BAND_KL < n - 1 ? k + SG_BAND_KL : n - 1;
            const double t = y[k];
            y[k] = y[f->perm[k]];
            y[f->perm[k]] = t;
            for (i = k + 1; i <= last; ++i) {
                y[i] -= SG_BAND_AT(A, i, k) * y[k];
            }
        }
        for (i = n - 1; i >= 0; --i) { /* column by column, as the large dense factors */
            const double x = y[i] * f->inv[i];
            const int first = i - SG_BAND_KL - SG_BAND_KU > 0 ? i - SG_BAND_KL - SG_BAND_KU : 0;
            y[i] = x;
            for (k = first; k < i; ++k) {
                y[k] -= SG_BAND_AT(A, k, i) * x;
            }
        }
        for (i = 0; i < n; ++i) {
            b[order[i]] = y[i];
        }
    }
#else
    SG_UNROLL
    for (k = 0; k < n; ++k) { /* the row swaps, in order (L's rows were swapped with them) */
        const double t = b[k];
        b[k] = b[f->perm[k]];
        b[f->perm[k]] = t;
    }
#if SG_N_UNKNOWNS < SG_LU_PANEL_FROM
    SG_UNROLL
    for (k = 0; k < n; ++k) {
        SG_UNROLL
        for (i = k + 1; i < n; ++i) {
            b[i] -= A[i * n + k] * b[k];
        }
    }
    SG_UNROLL
    for (i = n - 1; i >= 0; --i) { /* row by row: x_i = (b_i - sum_{j>i} U_ij x_j) / U_ii */
        double t = b[i];
        SG_UNROLL
        for (j = i + 1; j < n; ++j) {
            t -= A[i * n + j] * b[j];
        }
        b[i] = t * f->inv[i];
    }
#else
    (void)j;
    SG_NAME(substitute)(A, f->inv, b);
#endif
#endif /* SG_BANDED */
    return SG_NAME(norm_inf)(b, n) < INFINITY ? SG_OK : SG_NON_FINITE;
}

/* The column of the Jacobian that pivot k eliminates (the band order's in a band kernel) */
#if SG_BANDED
#define SG_PIVOT_COLUMN(k) SG_NAME(band_order)[k]
#else
#define SG_PIVOT_COLUMN(k) (k)
#endif

/* A cheap lower estimate of the condition of the row-equilibrated Jacobian, from the
 * reciprocal pivots of its factorisation: the smaller of max |pivot| / min |pivot| and the
 * same ratio with each pivot weighted by 1 + |u_J,j| for its column j (the condition of
 * J diag(1 + |u_J|), in which the updates are measured, SG_NAME(relative_norm)).  Column
 * weights leave the pivots' choice and the multipliers unchanged; an unknown far larger
 * than the others (a multiplier of 3e13 beside times of 100) otherwise makes its column's
 * pivot tiny against its row, and the unweighted ratio (1.7e14) declares any update noise */
static double SG_NAME(pivot_ratio)(const double *inv, const double *uJ)
{
    double lo = fabs(inv[0]), hi = lo;
    double wlo = lo / (1.0 + fabs(uJ[SG_PIVOT_COLUMN(0)])), whi = wlo;
    int k;
    for (k = 1; k < SG_N_UNKNOWNS; ++k) {
        const double a = fabs(inv[k]);
        const double w = a / (1.0 + fabs(uJ[SG_PIVOT_COLUMN(k)]));
        lo = a < lo ? a : lo;
        hi = a > hi ? a : hi;
        wlo = w < wlo ? w : wlo;
        whi = w > whi ? w : whi;
    }
    return whi / wlo < hi / lo ? whi / wlo : hi / lo; /* (an infinite weight: the first) */
}

/* C_i = DBL_EPSILON * sum_j |J_ij| |u_j|: how far F_i moves when the unknowns are rounded
 * (each sum from j = 0 up; the loop over i innermost) */
static void SG_NAME(coordinate_floor)(const double *J, const double *u, double *C)
{
    int i, j;
    SG_UNROLL
    for (i = 0; i < SG_N_EQUATIONS; ++i) {
        C[i] = 0.0;
    }
#if SG_BANDED
    {
        double a[SG_N_UNKNOWNS];
        for (j = 0; j < SG_N_UNKNOWNS; ++j) {
            a[j] = fabs(u[j]);
        }
        SG_NAME(column_sums)(J, a, C);
    }
#else
    SG_UNROLL
    for (j = 0; j < SG_N_UNKNOWNS; ++j) {
        const double a = fabs(u[j]);
        SG_UNROLL
        for (i = 0; i < SG_N_EQUATIONS; ++i) {
            C[i] += fabs(J[i * SG_N_UNKNOWNS + j]) * a;
        }
    }
#endif
    SG_UNROLL
    for (i = 0; i < SG_N_EQUATIONS; ++i) {
        C[i] *= DBL_EPSILON;
    }
}

/* 1 when every |F_i| <= 64 DBL_EPSILON kappa S_i, S_i = sum_j |J_ij| (1 + min(|u_j|, |u_J,j|))
 * (each sum from j = 0 up), kappa the pivot ratio of J's factorisation f: the residual is one
 * that an update at the rounding noise of a solve with that factorisation would leave
 * (F ~ J d).  J is the Jacobian evaluated at u_J, and the weights never exceed those at u_J,
 * so an iterate u that ran away from the solution (|u| ~ 1e90, where relative updates are
 * tiny and J vanishes) is not accepted for its small relative update.
 * The row sums R_i = sum_j |J_ij| of the factorisation decide first when every weight
 * a_j = 1 + min(...) is finite: then S_i >= R_i as computed (each rounded term |J_ij| a_j
 * >= |J_ij| since a_j >= 1, and rounding is monotone), so |F_i| <= bound R_i for every i
 * implies the test on S; otherwise S is computed.  The answer is exactly that of S alone. */
static int SG_NAME(explained_by_rounding)(const double *F, const double *J, const double *u, const double *uJ, const SG_NAME(lu) *f)
{
    const double bound = 64.0 * DBL_EPSILON * SG_NAME(pivot_ratio)(f->inv, uJ);
    double a[SG_N_UNKNOWNS], S[SG_N_EQUATIONS];
    uint64_t amax = 0;
    int i, j, below = 1;
    SG_UNROLL
    for (j = 0; j < SG_N_UNKNOWNS; ++j) {
        const uint64_t bits = SG_NAME(abs_bits)(a[j] = 1.0 + (fabs(u[j]) < fabs(uJ[j]) ? fabs(u[j]) : fabs(uJ[j])));
        amax = bits > amax ? bits : amax;
    }
    if (amax < SG_INF_BITS) {
        SG_UNROLL
        for (i = 0; i < SG_N_EQUATIONS; ++i) {
            below &= fabs(F[i]) <= bound * f->row_max[i];
        }
        if (below) {
            return 1;
        }
    }
    SG_UNROLL
    for (i = 0; i < SG_N_EQUATIONS; ++i) {
        S[i] = 0.0;
    }
#if SG_BANDED
    SG_NAME(column_sums)(J, a, S);
#else
    SG_UNROLL
    for (j = 0; j < SG_N_UNKNOWNS; ++j) {
        SG_UNROLL
        for (i = 0; i < SG_N_EQUATIONS; ++i) {
            S[i] += fabs(J[i * SG_N_UNKNOWNS + j]) * a[j];
        }
    }
#endif
    SG_UNROLL
    for (i = 0; i < SG_N_EQUATIONS; ++i) {
        if (!(fabs(F[i]) <= bound * S[i])) {
            return 0;
        }
    }
    return 1;
}

/* 1 when every |F_i| <= factor * (C_i + N_i): C_i the change of F_i when the unknowns are
 * rounded (SG_NAME(coordinate_floor), with the last factored Jacobian at the point where it
 * was evaluated) and N_i the larger
 * change of F_i when every unknown is moved by 4 ulps up or down (alternating signs), which
 * also measures the rounding of F's own operations: the residual is as small as rounding
 * lets it be -- an empirical floor, measured at the iterate rather than bounded */
static int SG_NAME(at_floor)(const double *u, const double *known, const double *p, const double *h, const double *F, const double *C, double factor)
{
    double v[SG_N_UNKNOWNS], G[SG_N_EQUATIONS], N[SG_N_EQUATIONS];
    int i, j, sign;
    for (i = 0; i < SG_N_EQUATIONS; ++i) {
        N[i] = C[i];
    }
    for (sign = -1; sign <= 1; sign += 2) {
        for (j = 0; j < SG_N_UNKNOWNS; ++j) {
            const double move = 4.0 * DBL_EPSILON * (fabs(u[j]) > DBL_MIN ? fabs(u[j]) : 1.0);
            v[j] = u[j] + ((j % 2 == 0) ? sign : -sign) * move;
        }
        SG_NAME(residual_hoisted)(v, known, p, h, G);
        for (i = 0; i < SG_N_EQUATIONS; ++i) {
            const double d = fabs(G[i] - F[i]);
            if (d > N[i] - C[i]) {
                N[i] = C[i] + d;
            }
        }
    }
    for (i = 0; i < SG_N_EQUATIONS; ++i) {
        if (!(fabs(F[i]) <= factor * N[i])) {
            return 0;
        }
    }
    return 1;
}

/* 1 when every |F_i| <= factor DBL_EPSILON S_i, S_i the size of the terms F_i is computed
 * from (SG_NAME(residual_scale)): F is within the rounding noise of its own evaluation, as
 * when a residual written in increments (x_{k+1} - x_k)/h is evaluated at positions far
 * from the origin, whose rounding no move of the (small) unknowns can undo */
static int SG_NAME(within_scale)(const double *u, const double *known, const double *p, const double *F, double factor)
{
    double S[SG_N_EQUATIONS];
    int i;
    SG_NAME(residual_scale)(u, known, p, S);
    for (i = 0; i < SG_N_EQUATIONS; ++i) {
        if (!(fabs(F[i]) <= factor * DBL_EPSILON * S[i])) {
            return 0;
        }
    }
    return 1;
}

#include "options.h"

/* max_j |d_j| / (1 + |u_j|): the size of an update relative to each unknown */
static inline double SG_NAME(relative_norm)(const double *d, const double *u)
{
    double m = 0.0;
    int j;
    for (j = 0; j < SG_N_UNKNOWNS; ++j) {
        const double a = fabs(d[j]) / (1.0 + fabs(u[j]));
        if (a > m) {
            m = a;
        }
    }
    return m;
}

/* 1 when some error factor |d_j| exceeds the rounding of u_j (DBL_EPSILON |u_j|): after an
 * update d with contraction rho (factor = rho/(1 - rho)), whether the estimated remaining
 * error is still above the rounding of u */
static inline int SG_NAME(above_rounding)(const double *d, const double *u, double factor)
{
    int j, above = 0;
    SG_UNROLL
    for (j = 0; j < SG_N_UNKNOWNS; ++j) {
        above |= factor * fabs(d[j]) > DBL_EPSILON * fabs(u[j]);
    }
    return above;
}

/* The largest update (relative to each unknown) that an iterate at a rounding floor may
 * still call for: a residual that the last factorisation would answer with a larger update
 * is not rounding, however large the terms it is computed from (a midpoint step on a group
 * at a large h, whose terms reach 1e15 while |F| ~ 5 and the update ~ 0.07-0.3).  At a true
 * floor the update is the rounding noise the floor allows: up to 5e-8 for the planar body
 * falling to 5e6 m (tests/test_newton_floors.py), 20 times below this bound.  (It was 1e-4:
 * runaways to the Cayley chart's cut locus, where F is the noise of its own evaluation,
 * called for 8e-5 and 1.05e-4.) */
#define SG_FLOOR_UPDATE 1e-6

/* max_j |d_j| / (1 + min(|u_j|, |g_j|)): an update relative to the smaller of the iterate u
 * and the guess g Newton started from, so that an iterate that ran away from the guess
 * (Cayley coordinates of 1e3-5e5 near the chart's cut locus, from guesses of order 1) is not
 * judged at the scale of its own runaway */
static double SG_NAME(floor_norm)(const double *d, const double *u, const double *g)
{
    double m = 0.0;
    int j;
    for (j = 0; j < SG_N_UNKNOWNS; ++j) {
        const double a = fabs(d[j]) / (1.0 + (fabs(u[j]) < fabs(g[j]) ? fabs(u[j]) : fabs(g[j])));
        if (a > m) {
            m = a;
        }
    }
    return m;
}

/* 1 when the update d the factorisation f gives for the residual F (written to d) is at
 * most SG_FLOOR_UPDATE relative to the iterate u and the guess g (SG_NAME(floor_norm)): u
 * is a fixed point of Newton to within the rounding the floor tests allow for */
static int SG_NAME(update_negligible)(const SG_NAME(lu) *f, const double *F, const double *u, const double *g, double *d)
{
    memcpy(d, F, SG_N_UNKNOWNS * sizeof *d);
    return SG_NAME(lu_apply)(f, d) == SG_OK && SG_NAME(floor_norm)(d, u, g) <= SG_FLOOR_UPDATE;
}

/* 1 when the residual F at u is at a rounding floor: a rounding-level update explains it
 * (SG_NAME(explained_by_rounding)) or it is within the rounding of the unknowns
 * (SG_NAME(at_floor), C filled here), and the update it calls for is negligible
 * (as SG_NAME(update_negligible); that update is left in d, for the polishing update).  The
 * last condition keeps a runaway iterate whose Jacobian is numerically singular from
 * passing: at a pivot ratio of 1e14 the first bound reaches |F| ~ 5e13 (a driven pendulum
 * on the time groupoid at h = 2, q jumping to 1.9e7), while that residual still calls for
 * an update of 1.6 relative to u */
static int SG_NAME(at_rounding_floor)(const double *F, const double *J, const double *u, const double *uJ, const double *g, const SG_NAME(lu) *f, const double *known, const double *p, const double *h, double *C, double floor_factor, double *d)
{
    if (!SG_NAME(explained_by_rounding)(F, J, u, uJ, f)) {
        SG_NAME(coordinate_floor)(J, uJ, C);
        if (!SG_NAME(at_floor)(u, known, p, h, F, C, floor_factor)) {
            return 0;
        }
    }
    return SG_NAME(update_negligible)(f, F, u, g, d);
}

/* An iterate whose |F|_inf exceeds its guess's by this factor is never taken for a rounding
 * floor: Newton has made the guess worse, and a floor is no larger than the residual's
 * rounding where Newton started.  A Lobatto IIIA-IIIB step of a heavy top on SO(3) at
 * h = 0.3 ran away to Cayley coordinates of 4e4 (a rotation within 1e-4 of a half-turn,
 * the chart's cut locus), where F is the noise of its own evaluation (|F| = 9e4, moved
 * by as much under 4 ulps of u) and passed the floor of the unknowns' rounding */
#define SG_GUESS_MARGIN 1e3

/* a chord update that cuts the residual by this factor or more shows an iterate off its
 * rounding floor (SG_NAME(chord_cuts)): at a true floor of F's terms (a body far from the
 * origin) the same trial leaves at least 0.006 of the residual (19,000 stalls of
 * tests/test_newton_floors.py's falling body), on a slow stretch of Newton at most 3e-5 */
#define SG_TRIAL_CUT 1e-3

/* 1 when the update the factorisation f gives for the residual F at u cuts the residual
 * by SG_TRIAL_CUT (the residual evaluated at u - d): u is not at a rounding floor but on a
 * slow stretch of Newton (a nearly singular Jacobian), however small F is against the size
 * of its terms -- a size that counts a difference such as t_{k+1} - t_k at its ends'
 * magnitudes, and can overstate F's rounding a millionfold */
static int SG_NAME(chord_cuts)(const SG_NAME(lu) *f, const double *F, const double *u, const double *known, const double *p, const double *h, double rnorm)
{
    double d[SG_N_UNKNOWNS], v[SG_N_UNKNOWNS], G[SG_N_EQUATIONS];
    int j;
    memcpy(d, F, sizeof d);
    if (SG_NAME(lu_apply)(f, d) != SG_OK) {
        return 0;
    }
    for (j = 0; j < SG_N_UNKNOWNS; ++j) {
        v[j] = u[j] - d[j];
    }
    SG_NAME(residual_hoisted)(v, known, p, h, G);
    return SG_NAME(norm_inf)(G, SG_N_EQUATIONS) <= SG_TRIAL_CUT * rnorm;
}

/* Newton's method for F(u; known, p) = 0 from the guess in u (overwritten by the result); h
 * holds SG_NAME(hoist)(known, p), the values of the known state that F and J read.
 * The Jacobian at the guess is factored before any convergence test, so every call checks
 * it at least once: a degenerate step is reported as SG_SINGULAR_JACOBIAN, never returned
 * as solved.  An update reuses the last factorisation (a chord step) while the previous update
 * reduced |F|_inf at least tenfold -- near the solution, where Newton's first update has
 * already brought the error to the square of the guess's -- and refactors otherwise.
 * The last factored Jacobian J is kept unfactored beside its factors, with the point u_J where
 * it was evaluated.  Converged:
 *  - after an update d_k (k >= 1) whose estimated remaining error rho/(1 - rho) |d_k| is at
 *    most tol_step, with rho = |d_k| / |d_{k-1}| the observed contraction and |.| relative to
 *    each unknown (max_j |d_j| / (1 + |u_j|)), or an update of at most 4 DBL_EPSILON (rounding
 *    noise of u): the update is applied and the residual evaluated there (it is the residual
 *    reported), and the iterate is accepted only if a rounding-level update explains that
 *    residual (SG_NAME(explained_by_rounding)), or failing that SG_NAME(at_floor), and the
 *    update the last factorisation gives for it is at most SG_FLOOR_UPDATE
 *    (SG_NAME(at_rounding_floor)); otherwise Newton goes on (a small relative update at a
 *    runaway iterate is not convergence);
 *    after a stop on the estimate, when the estimated error is above the rounding of u
 *    (rho/(1 - rho) |d_j| > DBL_EPSILON |u_j| for some j, d the last update) or rho is the
 *    ratio of the first two updates (which may overstate the contraction), the
 *    accepted iterate takes one more chord update from that residual, which costs no
 *    evaluation (a "polishing" update, counted in *iterations, applied only when smaller
 *    than the last update and within max_iterations): the remaining error, though within
 *    tol_step, is systematic, and a conserved quantity would drift by it at every step;
 *  - or when an update reduced |F|_inf less than tenfold (Newton is no longer converging
 *    fast) and was a Newton update (its Jacobian factored at the iterate it started from;
 *    a chord update may contract slowly without any stall), and every |F_i| is at most
 *    floor_factor times its change
 *    under a rounding-level move of the unknowns (SG_NAME(at_floor), with
 *    C_i = DBL_EPSILON sum_j |J_ij| |u_J,j|) and the update the last factorisation gives
 *    for that residual is at most SG_FLOOR_UPDATE relative to the smaller of the iterate
 *    and the guess (SG_NAME(update_negligible)): Newton has stalled on rounding noise;
 *  - or when such an update was a Newton update, and every |F_i| is at most floor_factor
 *    DBL_EPSILON S_i, S_i the size of the terms F_i is computed from
 *    (SG_NAME(within_scale)), the update is negligible as above, and a chord update
 *    would not cut the residual by SG_TRIAL_CUT (SG_NAME(chord_cuts), one more evaluation
 *    of F; if it would, Newton goes on): the residual is within the rounding of its own
 *    evaluation, which the unknowns cannot undo (large knowns: positions far from the
 *    origin);
 *  - or when |F|_inf <= tol_residual (an absolute tolerance, off by default).
 *  - or when a Newton update reduced |F|_inf less than tenfold and was at most
 *    64 DBL_EPSILON times the pivot ratio (SG_NAME(pivot_ratio): rounding noise of an update
 *    solved with that factorisation), a rounding-level update explains the residual
 *    (SG_NAME(explained_by_rounding)) and the update it calls for is negligible as above.
 * Not converged: SG_NOT_CONVERGED after max_iterations updates (the iteration cap) when
 * the iterate is not at the rounding floor (SG_NAME(at_rounding_floor); at the floor it
 * is accepted, as a linear step is after its one update);
 * SG_STALLED when the update is that rounding noise but the residual is above every
 * floor: Newton cannot improve the iterate.  No floor test accepts an iterate whose
 * |F|_inf exceeds its guess's by SG_GUESS_MARGIN.
 * *iterations is the number of updates made and *residual_norm the |F|_inf of the returned
 * iterate (before its polishing update). */
static int SG_NAME(newton_solve)(const double *known, const double *p, const double *h, const SG_NAME(options) *options, double *u, int *iterations, double *residual_norm)
{
    double F[SG_N_EQUATIONS], C[SG_N_EQUATIONS];
    double J[SG_JACOBIAN_ENTRIES], uJ[SG_N_UNKNOWNS], d[SG_N_UNKNOWNS], g0[SG_N_UNKNOWNS];
    SG_NAME(lu) lu;
    double previous = 0.0, last_step = 0.0, guess = 0.0;
    int it, i, status, slow, noise, worse, done = 0;
    int fresh = 0; /* the last update was a Newton update (J factored where it started) */
    for (it = 0;; ++it) {
        double rnorm, step;
        int here = 0; /* J factored at this iterate */
        if (it == 0) {
            SG_JACOBIAN(u, known, p, h, F, J);
        } else {
            SG_NAME(residual_hoisted)(u, known, p, h, F);
        }
        rnorm = SG_NAME(norm_inf)(F, SG_N_EQUATIONS);
        *iterations = it;
        *residual_norm = rnorm;
        if (!(rnorm < INFINITY)) {
            return SG_NON_FINITE;
        }
        if (it == 0) {
            guess = rnorm;
            memcpy(g0, u, sizeof g0);
        }
        worse = rnorm > SG_GUESS_MARGIN * guess; /* no floor: Newton made the guess worse */
        if (done && !worse) { /* after the final update: accepted only at the rounding floor */
            if (SG_NAME(at_rounding_floor)(F, J, u, uJ, g0, &lu, known, p, h, C, options->floor_factor, d)) {
                /* accepted; after a stop on the estimate, one more chord update from this
                 * residual (d), applied and counted when smaller than the last update */
                if (done == 2 && it < options->max_iterations
                    && SG_NAME(relative_norm)(d, u) < last_step) {
                    SG_UNROLL
                    for (i = 0; i < SG_N_UNKNOWNS; ++i) {
                        u[i] -= d[i];
                    }
                    *iterations = it + 1;
                }
                return SG_OK;
            }
        }
        done = 0; /* a small update, a residual above the floor: iterate on */
        if (it == 0) {
            memcpy(uJ, u, sizeof uJ);
            status = SG_NAME(lu_factor)(J, &lu);
            if (status != SG_OK) {
                return status;
            }
            here = 1;
        }
        if (rnorm <= options->tol_residual) {
            return SG_OK;
        }
        slow = it > 0 && !(rnorm <= 0.1 * previous);
        if (slow) {
            /* a chord update may contract slowly without any stall: only a Newton
             * update that did not reduce |F| tenfold is a stall, and rounding noise only
             * when it is a Newton update's (a pivot ratio of 1e10 from a tiny mass made a
             * chord update contracting 9.9-fold "noise": the constraint was left at 7e-5) */
            noise = fresh && last_step <= 64.0 * DBL_EPSILON * SG_NAME(pivot_ratio)(lu.inv, uJ);
            if (fresh && !worse) {
                int on_floor, in_scale;
                SG_NAME(coordinate_floor)(J, uJ, C);
                on_floor = SG_NAME(at_floor)(u, known, p, h, F, C, options->floor_factor);
                in_scale = !on_floor
                           && SG_NAME(within_scale)(u, known, p, F, options->floor_factor);
                if ((on_floor || in_scale) && SG_NAME(update_negligible)(&lu, F, u, g0, d)) {
                    if (on_floor || !SG_NAME(chord_cuts)(&lu, F, u, known, p, h, rnorm)) {
                        return SG_OK; /* at the rounding of the unknowns or of F's terms */
                    }
                    noise = 0; /* off the floor: Newton goes on from u */
                }
            }
            if (noise) {
                /* the update is rounding noise: accepted if it explains the residual */
                return !worse && SG_NAME(explained_by_rounding)(F, J, u, uJ, &lu)
                       && SG_NAME(update_negligible)(&lu, F, u, g0, d) ? SG_OK : SG_STALLED;
            }
        }
        if (it >= options->max_iterations) {
            /* the cap: an iterate at the rounding floor is a solution all the same (a
             * linear step solved by its one update, a guess that already solves it) */
            return !worse && SG_NAME(at_rounding_floor)(F, J, u, uJ, g0, &lu, known, p, h, C, options->floor_factor, d)
                   ? SG_OK : SG_NOT_CONVERGED;
        }
        if (slow) {
            SG_JACOBIAN(u, known, p, h, F, J);
            memcpy(uJ, u, sizeof uJ);
            status = SG_NAME(lu_factor)(J, &lu);
            if (status != SG_OK) {
                return status;
            }
            here = 1;
        }
        previous = rnorm;
        fresh = here;
        status = SG_NAME(lu_apply)(&lu, F);
        if (status != SG_OK) {
            return status;
        }
        step = SG_NAME(relative_norm)(F, u);
        SG_UNROLL
        for (i = 0; i < SG_N_UNKNOWNS; ++i) {
            u[i] -= F[i];
        }
        if (step <= 4.0 * DBL_EPSILON) { /* the update is rounding noise of u */
            done = 1;
        } else if (it > 0 && step < last_step) {
            const double rho = step / last_step;
            if (rho / (1.0 - rho) * step <= options->tol_step) {
                /* to be polished, unless the remaining error is below the rounding of u;
                 * always after two updates (it == 1), where rho is a single ratio and the
                 * first update also removed the guess's error in the unknowns that enter
                 * linearly (multipliers), so that rho underestimates the contraction */
                done = (it == 1 || SG_NAME(above_rounding)(F, u, rho / (1.0 - rho))) ? 2 : 1;
            }
        }
        last_step = step;
    }
}

/* Newton's method (SG_NAME(newton_solve)), and a solution accepted only inside the domain
 * of the window's terms: where every value of SG_NAME(domain) (the logarithms, square roots,
 * acos, ... of L, finite exactly where L is defined; docs/conventions.md section 11) is finite;
 * SG_OUTSIDE_DOMAIN otherwise (a root of the step equations where L is not defined).  A kernel
 * whose terms are defined everywhere has SG_N_DOMAIN 0 and no check. */
static int SG_NAME(newton)(const double *known, const double *p, const double *h, const SG_NAME(options) *options, double *u, int *iterations, double *residual_norm)
{
    int status = SG_NAME(newton_solve)(known, p, h, options, u, iterations, residual_norm);
#if SG_N_DOMAIN > 0
    if (status == SG_OK) {
        double D[SG_N_DOMAIN];
        SG_NAME(domain)(u, known, p, D);
        if (!isfinite(SG_NAME(norm_inf)(D, SG_N_DOMAIN))) {
            return SG_OUTSIDE_DOMAIN;
        }
    }
#endif
    return status;
}

/* One Newton solve from the guess in u (see SG_NAME(newton)).  Returns
 * SG_INVALID_ARGUMENT, writing nothing, for a null pointer, invalid options, or a
 * non-finite entry of known, p or the guess. */
int SG_NAME(solve_step)(const double *known, const double *p, const SG_NAME(options) *options, double *u, int *iterations, double *residual_norm)
{
    SG_NAME(options) defaults;
    if (options == NULL) {
        SG_NAME(default_options)(&defaults);
        options = &defaults;
    }
    if (known == NULL || u == NULL || iterations == NULL || residual_norm == NULL
        || (SG_N_PARAMETERS > 0 && p == NULL)
        || !SG_NAME(options_valid)(options)
        || !isfinite(SG_NAME(norm_inf)(known, SG_N_KNOWNS))
        || !isfinite(SG_NAME(norm_inf)(p, SG_N_PARAMETERS))
        || !isfinite(SG_NAME(norm_inf)(u, SG_N_UNKNOWNS))) {
        return SG_INVALID_ARGUMENT;
    }
    {
        double h[SG_HOISTED_ENTRIES];
        SG_NAME(hoist)(known, p, h);
        return SG_NAME(newton)(known, p, h, options, u, iterations, residual_norm);
    }
}

/* 1 when a warm start is usable: count in 0..3, quadratic 0 or 1 and its count solutions
 * finite */
static int SG_NAME(warm_start_valid)(const SG_NAME(warm_start) *warm)
{
    if (warm->count < 0 || warm->count > 3 || (warm->quadratic != 0 && warm->quadratic != 1)) {
        return 0;
    }
    return (warm->count < 1 || isfinite(SG_NAME(norm_inf)(warm->u_last, SG_N_UNKNOWNS)))
           && (warm->count < 2 || isfinite(SG_NAME(norm_inf)(warm->u_before, SG_N_UNKNOWNS)))
           && (warm->count < 3 || isfinite(SG_NAME(norm_inf)(warm->u_earlier, SG_N_UNKNOWNS)));
}

/* The two extrapolations of unknown i from the warm start: linear, 2 u_last - u_before, and
 * quadratic, 3 (u_last - u_before) + u_earlier */
static inline double SG_NAME(linear_guess)(const SG_NAME(warm_start) *warm, int i)
{
    return 2.0 * warm->u_last[i] - warm->u_before[i];
}

static inline double SG_NAME(quadratic_guess)(const SG_NAME(warm_start) *warm, int i)
{
    return 3.0 * (warm->u_last[i] - warm->u_before[i]) + warm->u_earlier[i];
}

/* The Newton guess extrapolated from the warm start (count >= 2): quadratic when it holds
 * three solutions and warm->quadratic, else linear */
static void SG_NAME(extrapolate)(const SG_NAME(warm_start) *warm, double *u)
{
    const int quadratic = warm->count == 3 && warm->quadratic;
    int i;
    for (i = 0; i < SG_N_UNKNOWNS; ++i) {
        u[i] = quadratic ? SG_NAME(quadratic_guess)(warm, i) : SG_NAME(linear_guess)(warm, i);
    }
}

/* The least motion the trust region of a step allows for (relative to each unknown; see
 * SG_NAME(trusted)): a run at rest may still be set moving */
#define SG_TRUST_FLOOR 1e-2

/* 1 when the solution u of a step lies in the trust region of its extrapolated guess (or
 * the check is off, factor = 0, or the warm start holds fewer than three solutions):
 * |u - guess| <= factor (m + SG_TRUST_FLOOR), |d| = max_j |d_j| / (1 + |u_last,j|)
 * (SG_NAME(relative_norm) at the last solution) and m the larger of the last two steps'
 * motions |u_last - u_before| and |u_before - u_earlier| (checked from the fourth step of a
 * run on: one motion alone can be a small one of an oscillation).  Extrapolation from smooth
 * motion misses the next solution by a fraction of a step's motion (at most twice the larger
 * of two motions for an oscillation of two to six steps a period); a solution much farther
 * away belongs to another branch
 * of the step equations, reached when the nearby root has disappeared (a fold of the step
 * map: the step h no longer resolves the motion). */
static int SG_NAME(trusted)(const SG_NAME(warm_start) *warm, const double *guess, const double *u, double factor)
{
    double far = 0.0, m = 0.0, radius;
    int i, inside = 1;
    if (!(factor > 0.0) || warm->count < 3) {
        return 1;
    }
    SG_UNROLL
    for (i = 0; i < SG_N_UNKNOWNS; ++i) {
        const double e = fabs(u[i] - guess[i]);
        far = e > far ? e : far;
    }
    if (far <= factor * SG_TRUST_FLOOR) {
        return 1; /* within the smallest radius (every weight 1 + |u_last,i| >= 1): implies
                   * the test below, which then needs no division */
    }
    SG_UNROLL
    for (i = 0; i < SG_N_UNKNOWNS; ++i) { /* m, with one division per unknown */
        const double a = fabs(warm->u_last[i] - warm->u_before[i]);
        const double b = fabs(warm->u_before[i] - warm->u_earlier[i]);
        const double r = (a > b ? a : b) / (1.0 + fabs(warm->u_last[i]));
        m = r > m ? r : m;
    }
    radius = factor * (m + SG_TRUST_FLOOR);
    SG_UNROLL
    for (i = 0; i < SG_N_UNKNOWNS; ++i) { /* |u_i - guess_i| <= radius (1 + |u_last,i|) */
        inside &= fabs(u[i] - guess[i]) <= radius * (1.0 + fabs(warm->u_last[i]));
    }
    return inside;
}

/* The time of a step on a time groupoid R x R x G (seed 000 section 6.3; SG_TIME_UNKNOWN >= 0:
 * t_{k+1} is unknown SG_TIME_UNKNOWN, t_k and t_{k-1} are knowns SG_TIME_KNOWN and
 * SG_TIME_BEFORE, and SG_TIME_ROW >= 0 is the equation of the time section; see
 * symgroupoid.stepper._time).  On such a step with an energy-preserving (unconstrained) time
 * step both the energy equation and the others fix mainly the velocity, so the Jacobian is
 * nearly singular along the step length: a guess O(h^2) off in G sends Newton's first update
 * across the pole t_{k+1} = t_k to the time-reversed root g_{k+1} = g_k^-1 (an exact solution
 * for every L_d with L_d(g^-1) = -L_d(g)).
 * SG_NAME(hold_time) first moves the guess onto the fixed-step equations (seed 000 Example
 * 6.2): Newton with t_{k+1} held at its guess, the time row replaced by t_{k+1} = guess, at
 * most SG_HOLD_ITERATIONS updates until one is at most SG_HOLD_TOLERANCE (relative; they
 * are not counted in the step's iterations); the guess is kept as it was when that fails (a
 * singular or non-finite system, or no convergence).  Only for a step without constraints
 * (SG_TIME_ROW = -1 otherwise: a constraint t_{k+1} - t_k = h(g) fixes the step itself). */
#define SG_HOLD_ITERATIONS 8
#define SG_HOLD_TOLERANCE 1e-8
/* the most a time step may grow or shrink in one step (SG_NAME(time_step_kept)) */
#define SG_STEP_RATIO 2.0

#if SG_TIME_ROW >= 0 && SG_TIME_UNKNOWN >= 0
/* The Newton update d = J^-1 F at u into d (SG_N_EQUATIONS doubles, as F), of the step
 * equations or, when held, of the fixed-step equations (the time row replaced by
 * t_{k+1} = its value); 0 when J is singular or not finite. */
static int SG_NAME(time_update)(const double *known, const double *p, const double *h, const double *u, int held, double *d)
{
    double J[SG_N_EQUATIONS * SG_N_UNKNOWNS];
    SG_NAME(lu) lu;
    int i;
    SG_JACOBIAN(u, known, p, h, d, J);
    if (held) {
        d[SG_TIME_ROW] = 0.0;
        for (i = 0; i < SG_N_UNKNOWNS; ++i) {
            J[SG_TIME_ROW * SG_N_UNKNOWNS + i] = 0.0;
        }
        J[SG_TIME_ROW * SG_N_UNKNOWNS + SG_TIME_UNKNOWN] = 1.0;
    }
    return SG_NAME(lu_factor)(J, &lu) == SG_OK && SG_NAME(lu_apply)(&lu, d) == SG_OK;
}
#endif

static void SG_NAME(hold_time)(const double *known, const double *p, const double *h, double *u)
{
#if SG_TIME_ROW >= 0 && SG_TIME_UNKNOWN >= 0
    double F[SG_N_EQUATIONS], x[SG_N_UNKNOWNS];
    int it, i;
    memcpy(x, u, sizeof x);
    for (it = 0; it < SG_HOLD_ITERATIONS; ++it) {
        double step;
        if (!SG_NAME(time_update)(known, p, h, x, 1, F)) {
            return; /* singular or not finite: the guess as it was */
        }
        step = SG_NAME(relative_norm)(F, x);
        for (i = 0; i < SG_N_UNKNOWNS; ++i) {
            x[i] -= F[i];
        }
        if (step <= SG_HOLD_TOLERANCE) {
            memcpy(u, x, sizeof x);
            return;
        }
    }
#else
    (void)known;
    (void)p;
    (void)h;
    (void)u;
#endif
}

/* The fallback of a step on a time groupoid whose tries have failed (SG_NAME(simulate)):
 * Newton on the time step alone, along the fixed-step solutions.  From the held guess u,
 * each round takes the full Newton update at u (whose time component is the update of the
 * energy equation e(t_{k+1}) = F_time(t_{k+1}, G(t_{k+1})) reduced to the held solutions
 * G: the Schur complement of the rest), keeps the new time step within
 * [1/SG_STEP_RATIO, SG_STEP_RATIO] times the last, and holds the result again
 * (SG_NAME(hold_time)); at most SG_SETTLE_ITERATIONS rounds, until the time update is at
 * most SG_HOLD_TOLERANCE (relative).  The full update alone, from a held guess, leaves the
 * rows of a second-order step (of size 1/h^3) far off their fixed-step solution when it
 * moves t_{k+1}, and Newton then left the window for a far root (a spline with damping on
 * R, h = 0.02: from h_k = 0.046 to the root at 0.075 by way of 0.28 and 5.9).  u is left as
 * the last held iterate; its rounds are not counted in the step's iterations. */
#define SG_SETTLE_ITERATIONS 12

#if SG_TIME_ROW >= 0 && SG_TIME_UNKNOWN >= 0
static void SG_NAME(settle_time)(const double *known, const double *p, const double *h, double *u)
{
    const double last = known[SG_TIME_KNOWN] - known[SG_TIME_BEFORE];
    const double low = last > 0.0 ? last / SG_STEP_RATIO : last * SG_STEP_RATIO;
    const double high = last > 0.0 ? last * SG_STEP_RATIO : last / SG_STEP_RATIO;
    double F[SG_N_EQUATIONS];
    int it, i;
    for (it = 0; it < SG_SETTLE_ITERATIONS; ++it) {
        double dt, t;
        if (!SG_NAME(time_update)(known, p, h, u, 0, F)) {
            return; /* singular or not finite: u as it is */
        }
        dt = F[SG_TIME_UNKNOWN];
        for (i = 0; i < SG_N_UNKNOWNS; ++i) {
            u[i] -= F[i];
        }
        t = u[SG_TIME_UNKNOWN] - known[SG_TIME_KNOWN];
        if (t < low) {
            u[SG_TIME_UNKNOWN] = known[SG_TIME_KNOWN] + low;
        } else if (t > high) {
            u[SG_TIME_UNKNOWN] = known[SG_TIME_KNOWN] + high;
        }
        SG_NAME(hold_time)(known, p, h, u);
        if (fabs(dt) <= SG_HOLD_TOLERANCE * (1.0 + fabs(u[SG_TIME_UNKNOWN]))) {
            return;
        }
    }
}
#endif

/* 1 when the solution u keeps the time step of a step on a time groupoid on its branch: its
 * step h_{k+1} = t_{k+1} - t_k has the sign of the last step h_k = t_k - t_{k-1} and
 * 1/SG_STEP_RATIO <= h_{k+1}/h_k <= SG_STEP_RATIO (or the check is off, factor = 0, or
 * the step has no time).  A step halving or doubling at once resolves nothing; the reversed
 * root has h_{k+1} = -h_k. */
static int SG_NAME(time_step_kept)(const double *known, const double *u, double factor)
{
#if SG_TIME_UNKNOWN >= 0
    const double ratio = (u[SG_TIME_UNKNOWN] - known[SG_TIME_KNOWN])
                         / (known[SG_TIME_KNOWN] - known[SG_TIME_BEFORE]);
    return !(factor > 0.0) || (ratio >= 1.0 / SG_STEP_RATIO && ratio <= SG_STEP_RATIO);
#else
    (void)known;
    (void)u;
    (void)factor;
    return 1;
#endif
}

/* Adds the solution u of a step to the warm start.  When it held three solutions, the next
 * guess is chosen by hindsight: quadratic = 1 when the quadratic extrapolation would have
 * guessed u more closely than the linear one (SG_NAME(relative_norm) of the errors).  Smooth
 * motion favours the quadratic (its error is O(h^3) against O(h^2)); an oscillation with
 * fewer than about six steps per period, where higher order extrapolates worse, the linear. */
static void SG_NAME(remember)(const double *u, SG_NAME(warm_start) *warm)
{
    if (warm->count == 3) {
        double linear[SG_N_UNKNOWNS], quadratic[SG_N_UNKNOWNS];
        int i;
        for (i = 0; i < SG_N_UNKNOWNS; ++i) {
            linear[i] = u[i] - SG_NAME(linear_guess)(warm, i);
            quadratic[i] = u[i] - SG_NAME(quadratic_guess)(warm, i);
        }
        warm->quadratic = SG_NAME(relative_norm)(quadratic, u) < SG_NAME(relative_norm)(linear, u);
    } else {
        warm->quadratic = 0; /* (a run restarted with count = 0 forgets the old choice) */
    }
    memcpy(warm->u_earlier, warm->u_before, sizeof warm->u_earlier);
    memcpy(warm->u_before, warm->u_last, sizeof warm->u_before);
    memcpy(warm->u_last, u, sizeof warm->u_last);
    if (warm->count < 3) {
        ++warm->count;
    }
}

/* 1 when the inputs of n_steps steps are given and finite: u[k * SG_N_INPUTS + j], the
 * inputs of the arrow step k computes (a kernel without inputs ignores u, which may be
 * NULL) */
static int SG_NAME(inputs_valid)(const double *u, long n_steps)
{
#if SG_N_INPUTS > 0
    long k;
    if (n_steps > 0 && u == NULL) {
        return 0;
    }
    for (k = 0; k < n_steps; ++k) {
        if (!isfinite(SG_NAME(norm_inf)(u + (size_t)k * SG_N_INPUTS, SG_N_INPUTS))) {
            return 0;
        }
    }
#else
    (void)u;
    (void)n_steps;
#endif
    return 1;
}

/* Advance n_steps steps from known0 into a caller buffer of `capacity` rows.
 * Writes states[0 .. n_steps] (row k at states + k * SG_N_KNOWNS), and iterations[k],
 * residual_norms[k] for k < n_steps; needs capacity >= n_steps + 1 (rows of states;
 * iterations and residual_norms hold at least capacity - 1 entries), else nothing is written
 * and SG_INVALID_ARGUMENT is returned.
 * The Newton guess of a step is SG_NAME(predict), or, when options->extrapolate is set and the
 * warm start holds the solutions of at least the last two steps, their extrapolation
 * (SG_NAME(extrapolate): linear, u ~ 2 u_last - u_before, or quadratic, chosen by hindsight in
 * SG_NAME(remember); chart coordinates and multipliers of consecutive steps), falling back to
 * SG_NAME(predict) if Newton fails from there or its solution lies outside the guess's trust
 * region (SG_NAME(trusted); iterations[k] counts both tries): a solution from either try
 * outside that region ends the run with SG_BRANCH_JUMP.  Without extrapolation the guess is
 * the prediction, and a solution outside the trust region of the extrapolation (from a run's
 * fourth step on) ends the run the same way.  On a time groupoid every guess is
 * first solved onto the fixed-step equations (SG_NAME(hold_time)), and a solution whose time
 * step leaves [1/SG_STEP_RATIO, SG_STEP_RATIO] times the last (SG_NAME(time_step_kept), from
 * the first step on) is outside in the same way; a step whose tries fail there gets one
 * more, from the prediction settled on its energy equation (SG_NAME(settle_time)).
 * warm (may be NULL: a fresh start) is updated with every solved step; starting the next
 * call from the last state of this one with the same warm start continues the run exactly:
 * a run split into calls gives bitwise the states of one call.  Set warm->count = 0 to start
 * a new run.
 * A forced kernel (SG_N_INPUTS > 0) reads u[k * SG_N_INPUTS + j], the inputs of the arrow step
 * k computes, into the last SG_N_INPUTS entries of its known state (docs/conventions.md,
 * section 20); the states written keep their own inputs there.  u may be NULL without inputs.
 * On failure returns the status, sets *failed_step = k (else -1; failed_step may be NULL)
 * and copies the last Newton iterate of that step to last_iterate (SG_N_UNKNOWNS
 * doubles; may be NULL); iterations[k] and residual_norms[k] describe the failed step,
 * states[k + 1 ..] are not written and warm still ends at step k - 1. */
int SG_NAME(simulate)(const double *known0, const double *p, const double *u, long n_steps, const SG_NAME(options) *options, SG_NAME(warm_start) *warm, double *states, long capacity, int *iterations, double *residual_norms, long *failed_step, double *last_iterate)
{
    SG_NAME(options) defaults;
    SG_NAME(warm_start) fresh;
    long k;
    if (failed_step != NULL) {
        *failed_step = -1;
    }
    if (options == NULL) {
        SG_NAME(default_options)(&defaults);
        options = &defaults;
    }
    if (warm == NULL) {
        memset(&fresh, 0, sizeof fresh);
        warm = &fresh;
    }
    if (known0 == NULL || states == NULL || iterations == NULL || residual_norms == NULL
        || (SG_N_PARAMETERS > 0 && p == NULL)
        || n_steps < 0 || capacity < 1 || n_steps > capacity - 1
        || !SG_NAME(options_valid)(options) || !SG_NAME(warm_start_valid)(warm)
        || !isfinite(SG_NAME(norm_inf)(known0, SG_N_KNOWNS))
        || !isfinite(SG_NAME(norm_inf)(p, SG_N_PARAMETERS))
        || !SG_NAME(inputs_valid)(u, n_steps)) {
        return SG_INVALID_ARGUMENT;
    }
    memmove(states, known0, sizeof(double) * SG_N_KNOWNS);
    for (k = 0; k < n_steps; ++k) {
#if SG_N_INPUTS > 0
        /* the state with the inputs of the arrow this step computes in its last slot (the
         * stored state keeps its own inputs there) */
        double current[SG_N_KNOWNS];
#else
        const double *current = states + (size_t)k * SG_N_KNOWNS;
#endif
        double next[SG_N_KNOWNS];
        double x[SG_N_UNKNOWNS], guess[SG_N_UNKNOWNS];
        double h[SG_HOISTED_ENTRIES]; /* SG_NAME(hoist) of this step's known state */
        const int extrapolated = options->extrapolate && warm->count >= 2;
        /* a step from the prediction (options->extrapolate off) is still checked against
         * the trust region of the extrapolation of the run's last solutions (which it does
         * not start from: the solution stays a function of the state) */
        const int watched = !extrapolated && warm->count >= 3;
        int status;
#if SG_N_INPUTS > 0
        memcpy(current, states + (size_t)k * SG_N_KNOWNS, sizeof current);
        memcpy(current + SG_N_KNOWNS - SG_N_INPUTS, u + (size_t)k * SG_N_INPUTS, sizeof(double) * SG_N_INPUTS);
#endif
        if (extrapolated) {
            SG_NAME(extrapolate)(warm, guess);
            memcpy(x, guess, sizeof x);
        } else {
            if (watched) {
                SG_NAME(extrapolate)(warm, guess);
            }
            SG_NAME(predict)(current, p, x);
        }
        SG_NAME(hoist)(current, p, h);
        SG_NAME(hold_time)(current, p, h, x);
        status = SG_NAME(newton)(current, p, h, options, x, &iterations[k], &residual_norms[k]);
        {
            /* a solution far outside the trust region of the guess, or with its time step
             * reversed or far from the last: another branch */
            const int jumped = status == SG_OK
                               && (((extrapolated || watched) && !SG_NAME(trusted)(warm, guess, x, options->trust_factor))
                                   || !SG_NAME(time_step_kept)(current, x, options->trust_factor));
            if (extrapolated && (status != SG_OK || jumped)) {
                /* the extrapolated guess failed or led far away: retry from the prediction */
                double far[SG_N_UNKNOWNS];
                const double far_norm = residual_norms[k];
                int more = 0;
                memcpy(far, x, sizeof far);
                SG_NAME(predict)(current, p, x);
                SG_NAME(hold_time)(current, p, h, x);
                status = SG_NAME(newton)(current, p, h, options, x, &more, &residual_norms[k]);
                iterations[k] = more > INT_MAX - iterations[k] ? INT_MAX : iterations[k] + more;
                if (status != SG_OK && jumped) { /* report the far solution */
                    memcpy(x, far, sizeof far);
                    residual_norms[k] = far_norm;
                }
                if (status == SG_OK ? !SG_NAME(trusted)(warm, guess, x, options->trust_factor)
                                          || !SG_NAME(time_step_kept)(current, x, options->trust_factor)
                                    : jumped) {
                    status = SG_BRANCH_JUMP;
                }
            } else if (jumped) { /* from the prediction: no other guess to try */
                status = SG_BRANCH_JUMP;
            }
        }
#if SG_TIME_ROW >= 0 && SG_TIME_UNKNOWN >= 0
        if (status != SG_OK) {
            /* the last try on a time groupoid: from the prediction settled on the energy
             * equation along the fixed-step solutions (SG_NAME(settle_time)) */
            double y[SG_N_UNKNOWNS], settled_norm;
            int more = 0, again;
            SG_NAME(predict)(current, p, y);
            SG_NAME(hold_time)(current, p, h, y);
            SG_NAME(settle_time)(current, p, h, y);
            again = SG_NAME(newton)(current, p, h, options, y, &more, &settled_norm);
            iterations[k] = more > INT_MAX - iterations[k] ? INT_MAX : iterations[k] + more;
            if (again == SG_OK && SG_NAME(time_step_kept)(current, y, options->trust_factor)
                && (!(extrapolated || watched) || SG_NAME(trusted)(warm, guess, y, options->trust_factor))) {
                memcpy(x, y, sizeof x);
                residual_norms[k] = settled_norm;
                status = SG_OK;
            }
        }
#endif
        if (status == SG_OK) {
            SG_NAME(next_knowns)(x, current, p, next);
            if (!isfinite(SG_NAME(norm_inf)(next, SG_N_KNOWNS))) {
                status = SG_NON_FINITE;
            }
        }
        if (status != SG_OK) {
            if (failed_step != NULL) {
                *failed_step = k;
            }
            if (last_iterate != NULL) {
                memcpy(last_iterate, x, sizeof x);
            }
            return status;
        }
        memcpy(states + (size_t)(k + 1) * SG_N_KNOWNS, next, sizeof next);
        SG_NAME(remember)(x, warm);
    }
    return SG_OK;
}
