# Regenerate every study of the thesis's chapter 4, the animations and the report.
#   make studies        (resumes: finished points are not solved again)
#   make clean-studies  (removes the study results, to start afresh)
#   make atlases        (the gait families covered: minutes per cell)
#   make controllers    (the controller comparisons: hours)
PY ?= .venv/bin/python
STUDIES = grid_downward grid_upward speed_sweep stable_region_random convergence_regions \
          body_angle_scan body_angle_fine_scan adaptive_upright adaptive_upright_tracking \
          optimal_downward optimal_upright
BRANCHES = continuation_slip_attack continuation_downward_speed continuation_downward_height \
           curve_slip_band curve_downward_boundary curve_downward_neimark_sacker
# Studies that read the curves' results.
AFTER_CURVES = stable_region_traced
# Models of one's own (model: slip, walker, ba-slip-described, models/hopper.py:HOPPER), and the three hip
# laws under one controllers study at two bodies: about 40 min in all (the PD law's at the
# thesis's body 11 min, the third law's there 7 min).
MODELS = slip_attack slip_band hopper hopper_atlas hopper_robot hopper_controllers hopper_sweep walker walker_atlas walker_controllers slip_walker_energy virtual_constraint \
         virtual_constraint_controllers virtual_constraint_human virtual_constraint_slow \
         hip_laws_thesis_pd hip_laws_thesis_vpp hip_laws_thesis_virtual_constraint \
         hip_laws_human_pd hip_laws_human_vpp hip_laws_human_virtual_constraint
GAITS = downward upward downward_period2 vpp vpp_human
# The reference bodies' gaits with no guess, and which gaits exist at their cells (a minute).
BODIES = human_pd_hanging human_pd_upright human_vpp_3ms robot_pd_hanging robot_pd_upright robot_vpp \
	families_human_pd families_robot_pd
# Under the virtual-pivot-point hip law: sweeps over the pivot, the speed and the height,
# at the thesis's scale and at human scale, the human gait's branch in the pivot and its
# period-doubling curve, the atlases and the stability-optimal search.
VPP_STUDIES = vpp_sweep_thesis vpp_sweep_thesis_low vpp_sweep_human vpp_sweep_human_height continuation_vpp_pivot \
	curve_vpp_pivot curve_vpp_fold atlas_vpp atlas_vpp_human optimal_vpp
# Atlases of the gait families (long: minutes per cell), and the controllers compared on
# the most stable upright gait the upright atlas found (its gait copied into the problem),
# and the stability NLP's cross-checks: of the upright atlas (from drawn starts, then from
# the atlas's polished gaits), and of the VPP descent.
ATLASES = atlas_upright atlas_upright_capped atlas_downward atlas_human_pd controllers_upright_best optimal_upright_schur optimal_vpp_schur

# The controllers compared on the shipped gaits, with basins of 4,000 starts in each of
# five boxes for every controller: about 4 h on a 2-core machine (their committed runs:
# 67 min hanging, 2.4 h upright, 19 and 13 min VPP), so `make studies` leaves them out and
# `make clean-studies` leaves their results alone.
CONTROLLERS = controllers_downward controllers_upright controllers_vpp controllers_vpp_human

.PHONY: studies clean-studies atlases controllers

studies:
	@for s in $(STUDIES) $(BRANCHES) $(AFTER_CURVES) $(VPP_STUDIES) $(MODELS); do $(PY) -m baslip.solve problems/$$s.yaml || exit 1; done
	@for g in $(GAITS) $(BODIES); do $(PY) -m baslip.solve problems/$$g.yaml || exit 1; done
	$(PY) examples/walking_and_running.py results results/walking_and_running
	$(PY) -m baslip.animate problems/downward.yaml problems/upward.yaml problems/vpp_human.yaml --out results/animation
	$(PY) -m baslip.report

atlases:
	@for s in $(ATLASES); do $(PY) -m baslip.solve problems/$$s.yaml || exit 1; done
	$(PY) examples/schur_from_atlas.py results/atlas_upright problems/atlas_upright.yaml results/schur_from_atlas

controllers:
	@for s in $(CONTROLLERS); do $(PY) -m baslip.solve problems/$$s.yaml || exit 1; done
	$(PY) -m baslip.report

clean-studies:
	rm -rf $(addprefix results/,$(STUDIES) $(BRANCHES) $(AFTER_CURVES) $(VPP_STUDIES) $(BODIES) $(MODELS)) results/animation \
		results/walking_and_running results/REPORT.md
