package driftfmu;

import java.io.IOException;
import java.io.PrintWriter;
import java.nio.file.Files;
import java.nio.file.Path;
import java.nio.file.Paths;
import java.util.ArrayList;
import java.util.LinkedHashMap;
import java.util.List;
import java.util.Map;

import org.javafmi.proxy.Status;
import org.javafmi.wrapper.v2.Access;

/**
 * A fixed-step FMI 2.0 co-simulation master on the JVM, written against JavaFMI's low-level
 * {@code Access} API (instantiate, setupExperiment, initialisation mode, doStep, get/set).
 *
 * <p>It runs the same loop as the project's fmpy master (simulations/cosim.py): at every
 * communication point the FMUs are stepped in the order given, then outputs are copied along the
 * connections in the order given (Gauss-Seidel), then the recorded variables are read.
 *
 * <p>Usage: {@code ChainHost SPEC OUT.csv}.  SPEC has one directive per line:
 * <pre>
 * fmu NAME PATH               load an FMU as instance NAME (stepped in file order)
 * start NAME VAR real|integer VALUE
 * connect SRC OUT DST IN      copy SRC.OUT to DST.IN at every communication point
 * input NAME VAR V1 V2 ...    drive DST.IN from a recorded signal, one value per point
 * record NAME VAR             write NAME.VAR as a column of OUT.csv
 * steps N                     number of communication points
 * step H                      communication step size [s]
 * order set-read|read-set     set-read (default): at each point set the inputs, then read the
 *                             outputs, as the project's master does; read-set: read the outputs
 *                             right after the step, then set the inputs of this point, as
 *                             fmpy's simulate_fmu and the FMI cross-check importers do
 * </pre>
 * Values are printed with {@link Double#toString}, which round-trips a double exactly.
 */
public final class ChainHost {

    private static final class Fmu {
        final String name;
        final Access access;

        Fmu(String name, String path) {
            this.name = name;
            this.access = new Access(path);
        }

        int vr(String var) {
            return access.getValueReference(var);
        }
    }

    private static void check(Status status, String what) {
        if (status != Status.OK && status != Status.WARNING) {
            throw new IllegalStateException(what + " returned " + status);
        }
    }

    private static String row(double t, List<String[]> records, Map<String, Fmu> fmus) {
        StringBuilder row = new StringBuilder(Double.toString(t));
        for (String[] r : records) {
            Fmu f = fmus.get(r[1]);
            row.append(',').append(Double.toString(f.access.getReal(f.vr(r[2]))[0]));
        }
        return row.toString();
    }

    public static void main(String[] args) throws IOException {
        if (args.length != 2) {
            System.err.println("usage: ChainHost SPEC OUT.csv");
            System.exit(2);
        }
        Map<String, Fmu> fmus = new LinkedHashMap<>();
        List<String[]> starts = new ArrayList<>();
        List<String[]> connections = new ArrayList<>();
        List<String[]> inputs = new ArrayList<>();
        List<String[]> records = new ArrayList<>();
        int steps = 0;
        double h = 0.0;
        boolean readFirst = false;
        for (String line : Files.readAllLines(Paths.get(args[0]))) {
            String[] w = line.trim().split("\\s+");
            switch (w[0]) {
                case "fmu": fmus.put(w[1], new Fmu(w[1], w[2])); break;
                case "start": starts.add(w); break;
                case "connect": connections.add(w); break;
                case "input": inputs.add(w); break;
                case "record": records.add(w); break;
                case "steps": steps = Integer.parseInt(w[1]); break;
                case "step": h = Double.parseDouble(w[1]); break;
                case "order": readFirst = w[1].equals("read-set"); break;
                case "": break;
                default: throw new IllegalArgumentException("unknown directive: " + line);
            }
        }

        for (Fmu f : fmus.values()) {
            f.access.instantiate(0.0);
            check(f.access.setUpExperiment(false, 0.0, 0.0, false, 0.0), f.name + " setupExperiment");
            check(f.access.enterInitializationMode(), f.name + " enterInitializationMode");
            for (String[] s : starts) {
                if (!s[1].equals(f.name)) continue;
                int[] vr = {f.vr(s[2])};
                if (s[3].equals("integer")) {
                    check(f.access.setInteger(vr, new int[] {Integer.parseInt(s[4])}), "set " + s[1] + "." + s[2]);
                } else {
                    check(f.access.setReal(vr, new double[] {Double.parseDouble(s[4])}), "set " + s[1] + "." + s[2]);
                }
            }
            check(f.access.exitInitializationMode(), f.name + " exitInitializationMode");
        }

        try (PrintWriter out = new PrintWriter(Files.newBufferedWriter(Paths.get(args[1])))) {
            StringBuilder header = new StringBuilder("time");
            for (String[] r : records) header.append(',').append(r[1]).append('.').append(r[2]);
            out.println(header);
            double t = 0.0;
            for (int i = 0; i < steps; i++) {
                if (i > 0) {
                    for (Fmu f : fmus.values()) check(f.access.doStep(t, h), f.name + " doStep at t=" + t);
                    t = i * h;
                }
                if (readFirst && i > 0) {
                    out.println(row(t, records, fmus));
                }
                for (String[] in : inputs) {
                    Fmu dst = fmus.get(in[1]);
                    check(dst.access.setReal(new int[] {dst.vr(in[2])}, new double[] {Double.parseDouble(in[3 + i])}),
                          "set " + in[1] + "." + in[2]);
                }
                for (String[] c : connections) {
                    Fmu src = fmus.get(c[1]);
                    Fmu dst = fmus.get(c[3]);
                    double[] v = src.access.getReal(src.vr(c[2]));
                    check(dst.access.setReal(new int[] {dst.vr(c[4])}, v), "set " + c[3] + "." + c[4]);
                }
                if (!readFirst || i == 0) {
                    out.println(row(t, records, fmus));
                }
            }
        }
        for (Fmu f : fmus.values()) {
            check(f.access.terminate(), f.name + " terminate");
            f.access.freeInstance();
        }
        System.out.println("javafmi: stepped " + String.join(", ", fmus.keySet()) + " for " + steps
                           + " communication points of " + h + " s");
    }
}
