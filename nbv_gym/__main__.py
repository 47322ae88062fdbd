"""``python -m nbv_gym``: the ``nbv-gym`` command line."""

from nbv_gym.cli.main import main

main()
