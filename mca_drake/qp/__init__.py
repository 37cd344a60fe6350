"""Small dense convex QPs, exact and hot-started: the NMPC's Gauss-Newton steps
(`mca_drake.cueing.nmpc_sqp`) and the hexapod's actuator clamp
(`mca_drake.platforms.leg_clamp`) solve theirs here. Plain numpy and LAPACK, at the
bottom of the layers so that every layer above may use them."""
