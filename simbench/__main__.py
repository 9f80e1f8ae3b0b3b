from simbench.cli.main import main

main()
