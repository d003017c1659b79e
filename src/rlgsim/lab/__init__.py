"""The lab: what joins the simulator and the estimators — studies, Monte Carlo, the digital twin, reports, recordings glue, the public API and the command line."""
