
/* the lanes of the written-out orders, 4 per vector where the compiler has GNU C's vector types
   (gcc, clang): each order's coefficients go into them as whole vectors and every sum over older
   coefficients is one vector expression (written out for a few vectors, else a loop over them);
   the compiler's own vectorizing of the lanes stored one double at a time and shuffled the scalar
   code into vectors, lengthening the chain from order to order (5-10 % slower). Elsewhere (or with
   -DKS_SCALAR_LANES) arrays of doubles, with the same sums in the same order: the same numbers */
#if defined(__GNUC__) && !defined(KS_SCALAR_LANES)
#define KS_VECTOR 1
typedef double ks_v4 __attribute__((vector_size(32)));
#define KS_V4(a, b, c, d) ((ks_v4){a, b, c, d})
#define KS_LANE(p) KS[(p) / 4][(p) % 4]
#else
#define KS_VECTOR 0
#define KS_LANE(p) KS[p]
#endif
