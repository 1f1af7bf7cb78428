//! SKiD evaluation metrics: PR curves, RTE/RRE/success, ATE/ARE with Umeyama and the paper's alpha/beta alignment, RPE, plots.
