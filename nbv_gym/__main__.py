from nbv_gym.cli import main

main()
