
#if defined(__GNUC__)
#define KS_OUTLINE __attribute__((noinline))
#else
#define KS_OUTLINE
#endif
/* out_i = sum_{k>=1} Y_i[k] tau^k (the increment), the components side by side (independent chains) */
static void ks_horner(double *const *Y, double tau, double *out)
{
    double s[TN_NY];
    int i, k;
    for (i = 0; i < TN_NY; ++i) s[i] = Y[i][TN_ORDER];
    for (k = TN_ORDER - 1; k >= 1; --k)
        for (i = 0; i < TN_NY; ++i) s[i] = s[i] * tau + Y[i][k];
    for (i = 0; i < TN_NY; ++i) out[i] = s[i] * tau;
}

/* ks_horner of the first TN_NY / 2 components (the coordinates), by the same sums */
static void ks_horner_coordinates(double *const *Y, double tau, double *out)
{
    double s[TN_NY / 2];
    int i, k;
    for (i = 0; i < TN_NY / 2; ++i) s[i] = Y[i][TN_ORDER];
    for (k = TN_ORDER - 1; k >= 1; --k)
        for (i = 0; i < TN_NY / 2; ++i) s[i] = s[i] * tau + Y[i][k];
    for (i = 0; i < TN_NY / 2; ++i) out[i] = s[i] * tau;
}

/* KS[p] = sum_{j=1}^{k-1} KA[j][p] KB[k-j][p] for every lane p: the older part of each convolution
   of order k, all at once (the compiler vectorizes over the lanes) */
static void ks_lanes(double *restrict KS, const double *restrict KA, const double *restrict KB, int k)
{
    int j, p;
    for (p = 0; p < TN_LANES; ++p) KS[p] = 0.0;
    for (j = 1; j + 1 < k; j += 2) {  /* the terms j and j + 1 in one pass: half the loads and stores of KS */
        const double *a = KA + j * TN_LANES, *b = KB + (k - j) * TN_LANES;
        const double *c = a + TN_LANES, *d = b - TN_LANES;
        for (p = 0; p < TN_LANES; ++p) KS[p] += a[p] * b[p] + c[p] * d[p];
    }
    if (j < k) {
        const double *a = KA + j * TN_LANES, *b = KB + (k - j) * TN_LANES;
        for (p = 0; p < TN_LANES; ++p) KS[p] += a[p] * b[p];
    }
}
