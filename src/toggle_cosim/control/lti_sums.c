/* toggle-cosim: a discrete LTI system's sample, the sums of control/lti.py's lti_step in its order:
   u = C x + D v and xn = A x + B v, each sum from 0.0, column 0 first, the input terms last, input
   0 first. A row by row (n x n), B row by row (n x m), C (n), D (m). Returns 0, or 1 where u or a
   next state is not finite (the caller hands the sample to the Python, which decides). Compile
   with -ffp-contract=off and without fast-math: then the C gives the Python's bits. */
static int lti_sums(long n, long m, const double *a, const double *b, const double *c, const double *d,
                    const double *x, const double *v, double *u, double *xn) {
    long i, j;
    double y = 0.0, acc;
    for (j = 0; j < n; j++) { y = y + c[j] * x[j]; }
    for (j = 0; j < m; j++) { y = y + d[j] * v[j]; }
    if (!isfinite(y)) { return 1; }
    for (i = 0; i < n; i++) {
        acc = 0.0;
        for (j = 0; j < n; j++) { acc = acc + a[i * n + j] * x[j]; }
        for (j = 0; j < m; j++) { acc = acc + b[i * m + j] * v[j]; }
        if (!isfinite(acc)) { return 1; }
        xn[i] = acc;
    }
    *u = y;
    return 0;
}
