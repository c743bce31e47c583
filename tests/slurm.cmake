# The batch path on a real scheduler: each test starts its own one-node Slurm cluster
# (jobs/slurm/local-cluster.sh, Debian's slurm-wlm and munge) in its scratch folder and stops
# it on exit. Skipped (exit 77) where slurmctld is not installed. cli_slurm_scripts needs no
# scheduler: shellcheck over jobs/ and a dry run of the PBS script (no PBS server available).
# Label `slurm`: ctest -L slurm. The RESOURCE_LOCK runs the clusters one at a time.
foreach(script cli_slurm_run cli_slurm_chain cli_slurm_sweep cli_slurm_srun)
  gen4d_cli_test(${script} TIMEOUT 300)
  if(TEST ${script})
    set_tests_properties(${script} PROPERTIES LABELS slurm SKIP_RETURN_CODE 77
                                              RESOURCE_LOCK slurm_cluster)
  endif()
endforeach()
# About 4 minutes (Slurm's time limits are whole minutes), nearly all of it waiting: its job's
# steps are paced by sleeps (GEN4D_TEST_STEP_SECONDS), so it holds one processor, not two.
if(TEST cli_slurm_chain)
  set_tests_properties(cli_slurm_chain PROPERTIES TIMEOUT 900 COST 300 PROCESSORS 1)
endif()
gen4d_cli_test(cli_slurm_scripts TIMEOUT 120)
if(TEST cli_slurm_scripts)
  set_tests_properties(cli_slurm_scripts PROPERTIES LABELS slurm SKIP_RETURN_CODE 77)
endif()
