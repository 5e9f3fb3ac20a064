"""``python -m zebra_sim_ros.cli`` runs ``zebra-sim``."""

from zebra_sim_ros.cli import main

raise SystemExit(main())
