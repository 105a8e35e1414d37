/* |x| as its bits, whose order as integers is the order of the numbers (NaN above infinity), and
   the greater of two: a maximum without a branch; the exponent is bits >> 52, less 1023 */
#define KS_INF_BITS 0x7ff0000000000000ULL
static inline uint64_t ks_abits(double x)
{
    uint64_t bits;
    memcpy(&bits, &x, sizeof bits);
    return bits & 0x7fffffffffffffffULL;
}

static inline uint64_t ks_umax(uint64_t a, uint64_t b) { return a > b ? a : b; }

static inline double ks_log2_bits(uint64_t bits)  /* log2 of the (positive, finite) double: e + m - 1, within 0.09 below */
{
    return (double)(int64_t)bits * 0x1p-52 - 1023;
}

static inline double ks_double(uint64_t bits)
{
    double x;
    memcpy(&x, &bits, sizeof x);
    return x;
}

/* log2 x (x > 0 finite) and 2^f, to about 4e-7, all a step size needs: from the bits of a double
   (IEEE 754) and polynomials fitted at Chebyshev points (Estrin's scheme), inline: pow was a call
   on the chain from step to step. A subnormal x reads as a larger one: a shorter step. */
static inline double ks_log2(double x)
{
    uint64_t bits;
    double m, t, t2;
    int e;
    memcpy(&bits, &x, sizeof bits);
    e = (int)((bits >> 52) & 0x7ff) - 1023;
    bits = (bits & 0x000fffffffffffffULL) | 0x3ff0000000000000ULL;
    memcpy(&m, &bits, sizeof m);  /* x = m 2^e, 1 <= m < 2 */
    t = m - 1.0;
    t2 = t * t;
    return e + (((3.685614096182563e-07 + 1.4426475487299142 * t) + (-0.7203160643589923 + 0.4720869162433963 * t) * t2)
                 + ((-0.32196028545952554 + 0.18875273773369058 * t) + (-0.07565137468285095 + 0.014440352494470008 * t) * t2)
                 * (t2 * t2));
}

static inline double ks_exp2(double f)
{
    uint64_t bits;
    double r, r2, scale;
    int n;
    f = f > 1000 ? 1000 : (f >= -1000 ? f : -1000);  /* a NaN too: (int) of it is undefined */
    n = (int)f;
    if (f < n) n -= 1;  /* floor */
    r = f - n;
    r2 = r * r;
    bits = (uint64_t)(n + 1023) << 52;
    memcpy(&scale, &bits, sizeof scale);  /* 2^n */
    return scale * (((0.9999998983500242 + 0.693154489663234 * r) + (0.24014181820142738 + 0.0558603370772849 * r) * r2)
                    + (0.008949590423295236 + 0.0018937540582203076 * r) * (r2 * r2));
}
