# Convenience aliases for the README's two commands.
.PHONY: demo test
demo:
	python3 bootstrap.py demo
test:
	python3 bootstrap.py test
