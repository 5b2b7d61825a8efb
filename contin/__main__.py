from contin.cli import main

main()
