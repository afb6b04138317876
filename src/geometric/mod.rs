//! Geometric errors: error tables, B-spline fits, the error model.
