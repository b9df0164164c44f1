# Writes OUT: a C++ file defining mfcd::daemon::embedded_sim_config() with the text of IN.
file(READ "${IN}" text)
file(WRITE "${OUT}.tmp" "// Generated from config/sim.yaml by daemon/embed_config.cmake; do not edit.\n"
     "namespace mfcd::daemon {\nconst char* embedded_sim_config() {\n  return R\"mfcd_yaml(${text})mfcd_yaml\";\n}\n}  // namespace mfcd::daemon\n")
file(COPY_FILE "${OUT}.tmp" "${OUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUT}.tmp")
