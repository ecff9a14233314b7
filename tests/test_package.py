import mimicrete as mc


def test_native_module_loads_and_exceptions_form_a_tree():
    assert mc.__version__ == "0.1.0"
    assert issubclass(mc.IkError, mc.MimicreteError)
    assert issubclass(mc.SimError, mc.MimicreteError)
    assert issubclass(mc.LogFormatError, mc.MimicreteError)
